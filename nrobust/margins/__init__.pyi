# The public names of nrobust.margins, loaded on first use (nrobust/margins/__init__.py).
from .admissible import (
    GainVerdict as GainVerdict,
    check_gain_end as check_gain_end,
    gain_verdict as gain_verdict,
    tolerates as tolerates,
)
from .axis import (
    AxisGap as AxisGap,
    AxisJet as AxisJet,
    frequency_bound as frequency_bound,
)
from .count import (
    UnstableCount as UnstableCount,
    unstable_count as unstable_count,
)
from .crossing import (
    Crossing as Crossing,
    CrossingSearch as CrossingSearch,
    crossing_frequencies as crossing_frequencies,
)
from .gain import (
    END_KINDS as END_KINDS,
    AffineGainLoop as AffineGainLoop,
    GainEnd as GainEnd,
    locate_gain_ends as locate_gain_ends,
)
from .margin import (
    DelayMargin as DelayMargin,
    delay_margin as delay_margin,
)
from .matrix import (
    GaugeRemainder as GaugeRemainder,
    circle_crossings as circle_crossings,
    compound_generator as compound_generator,
    compound_minors as compound_minors,
)
from .proven import (
    ProvenCrossings as ProvenCrossings,
    proven_crossings as proven_crossings,
    proven_gap as proven_gap,
    proven_zero_root as proven_zero_root,
)
