# The public names of nrobust.plots, loaded on first use (nrobust/plots/__init__.py).
from .base import (
    NrobustPlot as NrobustPlot,
    figure_png as figure_png,
)
from .bode import (
    BodeResponse as BodeResponse,
    bode_plot as bode_plot,
    bode_response as bode_response,
)
from .charts import (
    delay_chart_plot as delay_chart_plot,
    stability_chart_plot as stability_chart_plot,
    sweep_chart as sweep_chart,
    tradeoff_plot as tradeoff_plot,
)
from .design import (
    ParetoResponse as ParetoResponse,
    pareto_plot as pareto_plot,
    pareto_response as pareto_response,
)
from .nyquist import (
    NyquistResponse as NyquistResponse,
    nyquist_plot as nyquist_plot,
    nyquist_response as nyquist_response,
)
from .rootlocus import (
    RootLocusData as RootLocusData,
    root_locus_plot as root_locus_plot,
    root_locus_response as root_locus_response,
)
from .rootmap import (
    HiddenUnstableRoots as HiddenUnstableRoots,
    RootMapData as RootMapData,
    hidden_unstable_roots as hidden_unstable_roots,
    root_map_plot as root_map_plot,
    root_map_region as root_map_region,
    root_map_response as root_map_response,
)
from .simulation import (
    residual_floor as residual_floor,
    simulation_figure as simulation_figure,
    simulation_plot as simulation_plot,
)
