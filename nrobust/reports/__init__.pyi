# The public names of nrobust.reports, loaded on first use (nrobust/reports/__init__.py).
from .analyze import (
    run_analyze as run_analyze,
)
from .certificate import (
    CHECKED as CHECKED,
    FLOAT_SCOPE as FLOAT_SCOPE,
    PROVEN as PROVEN,
    Certificate as Certificate,
    Claim as Claim,
    ModelError as ModelError,
    PrincipalPart as PrincipalPart,
    certify as certify,
)
from .nplusm import (
    run_nplusm_analyze as run_nplusm_analyze,
)
from .outputs import (
    MANIFEST as MANIFEST,
    Manifest as Manifest,
    RunOutputs as RunOutputs,
    atomic_write as atomic_write,
    check_output_dir as check_output_dir,
    read_manifest as read_manifest,
)
from .paper import (
    PAPER_DELAYS_FIG1 as PAPER_DELAYS_FIG1,
    PAPER_DELAYS_FIG3 as PAPER_DELAYS_FIG3,
    PAPER_K as PAPER_K,
    PAPER_SYSTEM as PAPER_SYSTEM,
    PAPER_T_END as PAPER_T_END,
    paper_figure as paper_figure,
    run_paper as run_paper,
)
from .report import (
    RenderedFigures as RenderedFigures,
    ReportFiles as ReportFiles,
    certificate_figures as certificate_figures,
    render_certificate_figures as render_certificate_figures,
    render_nyquist_figure as render_nyquist_figure,
    write_report as write_report,
)
