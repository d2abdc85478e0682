"""Property-based, differential harness: no certified output of nrobust may
contradict an independent oracle (``tests/_oracles.py``), and bad input gets a named error.

Every nrobust call runs under a hard per-example deadline (``SIGALRM``) and a memory cap
(``RLIMIT_AS`` for the bad-input test), with warnings raised as errors, and is classified:
a result (whose certified claims are checked against the oracle), an honest refusal
(``CertificationError``/``ConvergenceError``, counted), or a contradiction (a refuted claim,
a valid input rejected, another exception type, a NaN result, a hang). Contradictions are
collected over the whole budget and each test fails at its end if it found any; the counts
are printed by ``tests/conftest.py``.

Budget: CI runs a fixed, derandomised set of examples (``max_examples`` per test below, the
whole file in well under a minute). ``NROBUST_FUZZ_EXAMPLES=N`` (``make fuzz``) runs ``N``
examples per unit weight of each test, random (not derandomised), with
``NROBUST_FUZZ_EXAMPLE_SECONDS`` as the per-example deadline.
"""

from __future__ import annotations

import inspect
import itertools
import math
import os
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, fields, is_dataclass
from fractions import Fraction
from functools import partial
from typing import Any

import mpmath as mp
import numpy as np
import pytest
from _budget import FUZZ
from _budget import budget as shared_budget
from _fuzzstats import STATS
from _guards import Hang, hard_deadline, memory_cap
from _oracles import (
    LoopOracle,
    NPlusMLoop,
    OracleUnsure,
    PDELoop,
    Profile,
    Speed,
    VaryingPDELoop,
    VaryingSpeedPDELoop,
    chain_abscissa,
    chain_roots,
    count_in_box,
    expand_roots,
    lambert_rightmost,
    lambert_roots,
    poly_from_roots,
    transport_k_interval,
    transport_margin,
    z_roots,
)
from hypothesis import assume, example, given
from hypothesis import strategies as st

import nrobust as nr
from nrobust import (
    CertificationError,
    ConvergenceError,
    DistributedDelay,
    ParameterError,
    QuasiPolynomial,
    ReflectionController,
    TransportSystem,
)
from nrobust.balls import ball_eval
from nrobust.hyperbolic.loops.controllers import loop_route
from nrobust.hyperbolic.loops.varying_proof import has_varying_proof, varying_proof
from nrobust.hyperbolic.nplusm import (
    NPlusMCharacteristic,
    NPlusMSystem,
    multi_actuator_delay_margin,
    nplusm_delay_margin,
)

# ============================================================================ budget
EXAMPLE_SECONDS = float(os.environ.get("NROBUST_FUZZ_EXAMPLE_SECONDS", "60" if FUZZ else "15"))
# Address-space cap above the current size for the bad-input test (a request for tens of
# GiB must fail fast as a named error, not swap the machine).
MEMORY_HEADROOM = 3 << 30

pytestmark = pytest.mark.timeout(0 if FUZZ else 240)
#: No shrinking: contradictions are collected, not raised; the hard per-example deadline of
#: ``EXAMPLE_SECONDS`` replaces hypothesis' own (no flaky re-runs).
budget = partial(shared_budget, shrink=False)


# ============================================================================ running nrobust
@dataclass
class Outcome:
    """``kind``: ``ok``, ``refused`` (CertificationError/ConvergenceError), ``rejected``
    (ParameterError/RegionError), ``wrong`` (any other exception, warnings included) or ``hang``."""

    kind: str
    value: Any = None
    error: BaseException | None = None

    def describe(self) -> str:
        return f"{self.kind}: {type(self.error).__name__}: {str(self.error)[:300]}" if self.error else self.kind


def call(fn: Callable[..., Any], *args: Any, seconds: float | None = None, **kwargs: Any) -> Outcome:
    """Run one nrobust call under the deadline, with warnings as errors, and classify it."""
    try:
        with hard_deadline(EXAMPLE_SECONDS if seconds is None else seconds), warnings.catch_warnings():
            warnings.simplefilter("error")
            value = fn(*args, **kwargs)
    except Hang as exc:
        return Outcome("hang", error=exc)
    except (CertificationError, ConvergenceError) as exc:
        return Outcome("refused", error=exc)
    except ParameterError as exc:
        return Outcome("rejected", error=exc)
    except Exception as exc:  # every other type (MemoryError and warnings included) is a defect
        return Outcome("wrong", error=exc)
    return Outcome("ok", value)


def settle(out: Outcome, test: str, what: str, case: Any) -> bool:
    """Book the non-result outcomes of a call on valid input; True iff there is a result to check."""
    if out.kind == "ok":
        return True
    if out.kind == "refused":
        STATS.refusal(test)
    elif out.kind == "rejected":
        STATS.contradiction(test, f"valid input rejected by {what}: {out.describe()}", case)
    elif out.kind in ("wrong", "hang"):
        STATS.contradiction(test, f"{out.kind} in {what}: {out.describe()}", case)
    return False


def run(prop: Callable[[], None], test: str) -> None:
    """Run a property over its budget, then fail if it collected contradictions."""
    before = len(STATS.contradictions)
    try:
        prop()
    finally:  # the contradictions found before an error of the harness itself are reported too
        new = [c for c in STATS.contradictions[before:] if c["test"] == test]
        for c in new:
            print(f"contradiction in {test}: {c['what']}\n    case: {c['case']}")
    if new:
        lines = [f"{len(new)} contradiction(s) in {test}:"] + [
            f"- {c['what']}\n    case: {c['case']}" for c in new[:40]
        ]
        pytest.fail("\n".join(lines), pytrace=False)


def unsure_guard(fn: Callable[[], Any]) -> Any:
    """Evaluate an oracle; None (case skipped, counted) when it is unsure."""
    try:
        return fn()
    except OracleUnsure:
        STATS.unsure()
        return None


# ============================================================================ strategies
def dyadic(lo: float, hi: float, bits: int = 3) -> st.SearchStrategy[float]:
    """Multiples of ``2^-bits`` in ``[lo, hi]``: exact in binary, so products stay exact."""
    return st.integers(math.ceil(lo * 2**bits), math.floor(hi * 2**bits)).map(lambda m: m / 2**bits)


def nonzero_dyadic(lo: float, hi: float, bits: int = 3) -> st.SearchStrategy[float]:
    """``+-`` a dyadic number of modulus in ``[lo, hi]``."""
    return st.tuples(dyadic(lo, hi, bits), st.booleans()).map(lambda t: -t[0] if t[1] else t[0]).filter(bool)


@st.composite
def root_sets(draw: st.DrawFn) -> list[complex]:
    """Roots of a real polynomial (pairs given once, ``Im > 0``), degree 1..6, some repeated."""
    n_real = draw(st.integers(0, 3))
    n_pair = draw(st.integers(0 if n_real else 1, 2))
    roots = [complex(draw(dyadic(-4, 1)), 0.0) for _ in range(n_real)]
    roots += [complex(draw(dyadic(-4, 1)), draw(dyadic(0.125, 6))) for _ in range(n_pair)]
    if draw(st.booleans()) and len(expand_roots(roots)) <= 4:
        roots.append(draw(st.sampled_from(roots)))  # a double root (or pair)
    return roots


@dataclass
class KnownRoots:
    """A quasi-polynomial with its exact roots: ``lead p(s/f) D(e^{-h s})`` (``D = 1`` for a polynomial)."""

    F: QuasiPolynomial
    poly_roots: list[complex]  # roots of p, written out with conjugates
    z: np.ndarray | None  # roots of D, or None
    h: float
    description: str

    def roots_in(self, box: tuple[float, float, float, float]) -> list[complex]:
        out = [r for r in self.poly_roots]
        if self.z is not None:
            out += chain_roots(self.z, self.h, box)
        return out

    def abscissa(self) -> float:
        vals = [r.real for r in self.poly_roots]
        if self.z is not None:
            vals.append(chain_abscissa(self.z, self.h))
        return max(vals)

    def scale(self) -> float:
        return 1.0 + max(abs(r) for r in self.poly_roots)


@st.composite
def known_root_functions(draw: st.DrawFn) -> KnownRoots | None:
    """Products of a polynomial with known roots and a z-polynomial of commensurate delays."""
    base = draw(root_sets())
    f = 2.0 ** draw(st.integers(-8, 12))  # frequency scale: exact (roots up to |s| ~ 1e5)
    base = [complex(r.real * f, r.imag * f) for r in base]
    lead = 2.0 ** draw(st.integers(-30, 30))  # tiny and huge coefficients
    try:
        p = poly_from_roots(base, lead)
    except OracleUnsure:
        return None
    kind = draw(st.sampled_from(["poly", "poly", "exp", "z"]))
    roots = expand_roots(base)
    if kind == "poly":
        return KnownRoots(QuasiPolynomial([p], [0.0]), roots, None, 1.0, f"lead {lead:g} prod (s - r), r = {base}")
    h = draw(dyadic(0.125, 8)) / f
    if kind == "exp":
        c = [1.0, draw(nonzero_dyadic(0.125, 2))]
    else:
        n = draw(st.integers(2, 3))
        c = [1.0] + [draw(st.integers(-24, 24)) / 16 for _ in range(n - 1)] + [draw(st.integers(1, 24)) / 16]
    coefs = []
    for ck in c:
        exact = [Fraction(ck) * Fraction(v) for v in p]
        coefs.append([float(v) for v in exact])
        if any(Fraction(float(v)) != v for v in exact):
            return None
    z = unsure_guard(lambda: z_roots(c))
    if z is None:
        return None
    delays = [k * h for k in range(len(c))]
    if any(Fraction(d) != k * Fraction(h) for k, d in enumerate(delays)):
        return None
    F = QuasiPolynomial(coefs, delays)
    return KnownRoots(F, roots, z, h, f"lead {lead:g} prod (s - r) * D(e^(-{h:g} s)), r = {base}, D = {c}")


@st.composite
def boxes_for(draw: st.DrawFn, center: complex, spread: float, height: float) -> tuple[float, float, float, float]:
    """A rectangle about ``center``: widths and heights drawn on the scale ``spread``/``height``."""
    fr = st.floats(0.05, 1.5)
    x0 = center.real - draw(fr) * spread
    x1 = center.real + draw(fr) * spread
    y0 = center.imag - draw(fr) * height
    y1 = center.imag + draw(fr) * height
    return (x0, x1, y0, y1)


# ============================================================================ checks shared by root tests
def check_count(
    test: str, F: QuasiPolynomial, box: tuple, truth_in: Callable[[tuple], list[complex]], scale: float, case: Any
) -> None:
    out = call(nr.count_roots, F, box)
    if not settle(out, test, "count_roots", case):
        return
    rc = out.value
    truth = unsure_guard(lambda: count_in_box(truth_in(rc.region), rc.region, 1e-9 * scale))
    if truth is not None:
        STATS.claim(int(rc) == truth, test, f"count_roots: {int(rc)} roots, truth {truth} in {rc.region}", case)


def check_find(
    test: str, F: QuasiPolynomial, box: tuple, truth_in: Callable[[tuple], list[complex]], scale: float, case: Any
) -> None:
    out = call(nr.find_roots, F, box)
    if not settle(out, test, "find_roots", case):
        return
    rs = out.value
    reg = rs.region
    inside = unsure_guard(lambda: [r for r in truth_in(reg) if count_in_box([r], reg, 1e-9 * scale)])
    if inside is None:
        return
    STATS.claim(rs.count == len(inside), test, f"find_roots count: {rs.count}, truth {len(inside)} in {reg}", case)
    if not rs.certified:
        STATS.refusal(test)
        return
    slack = 1e-9 * scale
    STATS.claim(
        int(np.sum(rs.multiplicities)) == len(inside),
        test,
        f"find_roots: certified multiplicities add to {int(np.sum(rs.multiplicities))}, truth {len(inside)}",
        case,
    )
    for r in inside:
        near = np.abs(rs.roots - r) <= rs.radii + slack
        STATS.claim(
            bool(near.any()), test, f"find_roots: exact root {r} not within the radius of any reported root", case
        )
    for z, m, rad in zip(rs.roots, rs.multiplicities, rs.radii):
        k = sum(abs(r - z) <= rad + slack for r in inside)
        STATS.claim(
            k >= m, test, f"find_roots: reported root {z} (mult {m}, radius {rad:.3g}) holds {k} exact roots", case
        )


def check_abscissa(test: str, F: QuasiPolynomial, truth: float, scale: float, case: Any, rtol: float = 1e-6) -> None:
    out = call(nr.spectral_abscissa, F)
    if not settle(out, test, "spectral_abscissa", case):
        return
    sa = out.value
    tol = rtol * scale
    STATS.claim(
        not math.isnan(sa.upper_bound) and truth <= sa.upper_bound + tol,
        test,
        f"spectral_abscissa: upper_bound {sa.upper_bound!r} below the rightmost root {truth!r}",
        case,
    )
    if not sa.certified:
        STATS.refusal(test)
        return
    STATS.claim(
        abs(sa.value - truth) <= tol,
        test,
        f"spectral_abscissa: certified value {sa.value!r}, truth {truth!r}",
        case,
    )
    if sa.root is not None and np.isfinite(sa.value):
        # Differential: a certified search in a box about the reported value finds nothing to its right.
        y = abs(sa.root.imag)
        box = (sa.value - 0.5 * scale, sa.value + 0.5 * scale, -y - 0.5 * scale, y + 0.5 * scale)
        fr = call(nr.find_roots, F, box)
        if settle(fr, test, "find_roots about the abscissa", case) and fr.value.certified and len(fr.value):
            right = float(np.max(fr.value.roots.real))
            STATS.claim(
                right <= sa.value + tol,
                test,
                f"spectral_abscissa {sa.value!r} but find_roots finds Re s = {right!r} in {box}",
                case,
            )


# ============================================================================ 1. known roots
@budget(ci=10, weight=1.0)
@given(known_root_functions(), st.data())
def _prop_known_roots(kr: KnownRoots | None, data: st.DataObject) -> None:
    test = "known_roots"
    if kr is None:
        STATS.unsure()
        return
    STATS.case()
    case = kr.description
    scale = kr.scale()
    center = complex(kr.abscissa(), 0.0)
    height = max(abs(r.imag) for r in kr.poly_roots) + (12.0 / kr.h if kr.z is not None else 1.0)
    height = min(height, 40.0 * scale)
    box = data.draw(boxes_for(center, scale, height))
    check_count(test, kr.F, box, kr.roots_in, scale, (case, box))
    check_find(test, kr.F, box, kr.roots_in, scale, (case, box))
    if kr.F.kind != "advanced":
        check_abscissa(test, kr.F, kr.abscissa(), scale, case)


def test_known_roots() -> None:
    """count_roots, find_roots and spectral_abscissa against exact roots of products."""
    run(_prop_known_roots, "known_roots")


# ============================================================================ 2. Lambert W family
@st.composite
def lambert_cases(draw: st.DrawFn) -> tuple[float, float, float, float, str]:
    """``(a, b, tau, lead, form)``: ``lead (s + a + b e^{-tau s})``, as point terms or with a
    constant-kernel distributed delay ``alpha s + beta + s int_0^tau c e^{-nu s} dnu``."""
    a = draw(dyadic(-3, 3))
    b = draw(nonzero_dyadic(1 / 16, 4, bits=4))
    tau = draw(dyadic(1, 8)) * 2.0 ** draw(st.integers(-3, 3))  # up to 64: long delays
    lead = 2.0 ** draw(st.integers(-20, 20))
    form = draw(st.sampled_from(["point", "point", "distributed"]))
    return a, b, tau, lead, form


def lambert_function(a: float, b: float, tau: float, lead: float, form: str) -> QuasiPolynomial:
    if form == "point":
        return QuasiPolynomial([[lead * a, lead], [lead * b]], [0.0, tau])
    # alpha s + beta + c (1 - e^{-tau s}) with alpha = lead, c = -lead b, beta = lead a - c
    c = -lead * b
    kernel = DistributedDelay(np.linspace(0.0, tau, 5), np.full(5, c), [0.0, 1.0])
    return QuasiPolynomial([[lead * a - c, lead]], [0.0], [kernel])


@budget(ci=10, weight=1.0)
@given(lambert_cases(), st.data())
def _prop_lambert(params: tuple, data: st.DataObject) -> None:
    test = "lambert"
    a, b, tau, lead, form = params
    STATS.case()
    F = lambert_function(*params)
    case = f"{lead:g} (s + {a!r} + {b!r} e^(-{tau!r} s)) [{form}]"
    r0 = lambert_rightmost(a, b, tau)
    scale = 1.0 + abs(r0) + abs(a) + abs(b)
    height = abs(r0.imag) + min(30.0, 20.0 / tau + 2.0)

    def truth_in(box: tuple) -> list[complex]:
        return list(lambert_roots(a, b, tau, max(abs(box[2]), abs(box[3])) + 1.0))

    box = data.draw(boxes_for(complex(r0.real, 0.0), 1.0 + abs(r0.real), height))
    if unsure_guard(lambda: lambert_roots(a, b, tau, 1.0)) is None:
        return
    check_count(test, F, box, truth_in, scale, (case, box))
    check_find(test, F, box, truth_in, scale, (case, box))
    check_abscissa(test, F, r0.real, scale, case)


def test_lambert_family() -> None:
    """Rightmost roots of ``s + a + b e^{-tau s}`` (principal branch of W), point and distributed forms."""
    run(_prop_lambert, "lambert")


# ============================================================================ 3. loops A + B e^{-delta s}
@st.composite
def loops(draw: st.DrawFn) -> tuple[list[float], list[float], str] | None:
    """Real polynomial loops of degree <= 3, with families that stress the crossing search."""
    # weighted towards the families that stress the crossing search
    kind = draw(st.sampled_from(["generic", "undamped", "undamped", "light", "light", "tangent", "tangent", "neutral"]))
    if kind == "generic":
        roots = draw(root_sets().filter(lambda r: len(expand_roots(r)) <= 3))
        a = poly_from_roots(roots)
        m = draw(st.integers(0, len(a) - 2))
        b = [draw(dyadic(-4, 4)) for _ in range(m)] + [draw(nonzero_dyadic(0.125, 4))]
    elif kind in ("undamped", "light"):
        w = draw(dyadic(0.25, 4))
        zeta = 0.0 if kind == "undamped" else 2.0 ** -draw(st.integers(4, 14))
        a = [w * w, 2.0 * zeta * w, 1.0]
        if draw(st.booleans()):  # a monomial B: the crossing sits exactly on the triangle bound
            j = draw(st.integers(0, 1))
            b = [0.0] * j + [draw(nonzero_dyadic(0.125, 4))]
        else:
            b = [draw(nonzero_dyadic(0.125, 4)), draw(dyadic(-4, 4))]
    elif kind == "tangent":
        # P(x) = (x - x0)^2 exactly: A = s^2 + u s + v^2 + u^2/4, B = u v, x0 = v^2 - u^2/4
        u = draw(dyadic(0.125, 4))
        v = draw(dyadic(0.125, 4).filter(lambda v: v > u / 2))
        a, b = [v * v + u * u / 4, u, 1.0], [u * v]
    else:  # neutral: deg B = deg A, |b_n| < |a_n|
        roots = draw(root_sets().filter(lambda r: len(expand_roots(r)) <= 3))
        a = poly_from_roots(roots)
        b = [draw(dyadic(-4, 4)) for _ in range(len(a) - 1)] + [draw(nonzero_dyadic(0.125, 0.875))]
    if kind in ("undamped", "light", "tangent") and draw(st.booleans()):
        c = draw(dyadic(0.125, 4))  # a common stable factor (s + c), with B's possibly mirrored
        sign = draw(st.sampled_from([1.0, -1.0]))
        a = [float(v) for v in np.polynomial.polynomial.polymul(a, [c, 1.0])]
        b = [float(v) for v in np.polynomial.polynomial.polymul(b, [sign * c, 1.0])]
    # scale and frequency scaling (exact: powers of two)
    g = 2.0 ** draw(st.integers(-30, 30))
    f = 2.0 ** draw(st.integers(-5, 5))
    a = [g * v * f**k for k, v in enumerate(a)]
    b = [g * v * f**k for k, v in enumerate(b)]
    if all(v == 0 for v in b):
        return None
    return a, b, kind


def _loop_case(a: list[float], b: list[float], kind: str, dmax: float | None, verify: bool) -> str:
    return f"{kind}: A = {a}, B = {b}, delta_max = {dmax}, verify = {verify}"


def nominally_stable(dm: Any) -> bool:
    """``DelayMargin.nominally_stable`` (``nominal_stable`` before its rename), read without a warning."""
    names = {f.name for f in fields(dm)}
    return bool(getattr(dm, "nominally_stable" if "nominally_stable" in names else "nominal_stable"))


def check_margin(test: str, o: LoopOracle, dm: Any, case: str) -> None:
    """The certified parts of a DelayMargin against the classical crossing analysis."""
    claim = STATS.claim
    claim(bool(dm.strongly_stable), test, "delay_margin: strongly stable loop reported not strongly stable", case)
    if o.nominal_unstable is not None and not o.zero_root:
        if dm.nominal_unstable is not None:
            claim(
                dm.nominal_unstable == o.nominal_unstable,
                test,
                f"delay_margin: nominal count {dm.nominal_unstable}, truth {o.nominal_unstable}",
                case,
            )
        stable = nominally_stable(dm)
        claim(
            stable == (o.nominal_unstable == 0),
            test,
            f"delay_margin: nominally stable {stable}, truth {o.nominal_unstable} unstable roots",
            case,
        )
    truth = o.margin
    if o.zero_root or o.nominal_unstable is not None:
        ok = (dm.margin == truth) if truth in (0.0, math.inf) else abs(dm.margin - truth) <= 1e-6 * truth
        claim(ok, test, f"delay_margin: margin {dm.margin!r}, truth {truth!r}", case)
    if o.nominal_unstable is None or o.zero_root:
        return
    # crossings: every oracle crossing up to delta_max reported with its direction and first delay
    for c in o.crossings:
        first = c.theta / c.omega
        if first > dm.delta_max or first == 0.0:
            continue
        match = [x for x in dm.crossings if abs(abs(x.omega) - c.omega) <= 1e-6 * c.omega]
        claim(bool(match), test, f"delay_margin: crossing w = {c.omega!r} (delta_0 = {first!r}) missed", case)
        if match and c.multiplicity == 1:
            x = match[0]
            claim(
                x.direction == c.direction,
                test,
                f"delay_margin: crossing w = {c.omega!r} direction {x.direction}, truth {c.direction}",
                case,
            )
            claim(
                abs(x.delays[0] - first) <= 1e-6 * (first + 1e-300),
                test,
                f"delay_margin: crossing w = {c.omega!r} delta_0 {x.delays[0]!r}, truth {first!r}",
                case,
            )
    for x in dm.crossings:
        known = any(abs(abs(x.omega) - c.omega) <= 1e-6 * c.omega for c in o.crossings)
        claim(known, test, f"delay_margin: reported crossing w = {x.omega!r} is not a zero of |A|^2 - |B|^2", case)
    # stability windows and counts at sampled delays away from every crossing delay
    hi = dm.delta_max if np.isfinite(dm.delta_max) else 4.0 * max([c.theta / c.omega for c in o.crossings] + [1.0])
    marks = o.crossing_delays(hi) + [d for x in dm.crossings for d in x.delays]
    for t in np.linspace(0.0, 1.0, 9)[1:]:
        d = float(t * hi)
        if any(abs(d - m) <= 1e-6 * max(d, 1e-300) for m in marks) or d > dm.delta_max:
            continue
        n = unsure_guard(lambda d=d: o.unstable_count(d))
        if n is None:
            continue
        got = call(dm.unstable_count, d)
        if got.kind != "ok":
            STATS.contradiction(test, f"DelayMargin.unstable_count({d!r}): {got.describe()}", case)
            continue
        claim(
            int(got.value) == n,
            test,
            f"delay_margin: {int(got.value)} unstable roots at delta = {d!r}, truth {n}",
            case,
        )
        stable = call(dm.is_stable, d)
        if stable.kind == "ok":
            claim(
                bool(stable.value) == (n == 0),
                test,
                f"delay_margin: is_stable({d!r}) = {stable.value}, truth {n} roots",
                case,
            )


@budget(ci=16, weight=1.5)
@given(loops(), st.data())
def _prop_loops(loop: tuple | None, data: st.DataObject) -> None:
    test = "loops"
    if loop is None:
        STATS.unsure()
        return
    a, b, kind = loop
    o = unsure_guard(lambda: LoopOracle(a, b))
    if o is None:
        return
    STATS.case()
    A, B = QuasiPolynomial([a], [0.0]), QuasiPolynomial([b], [0.0])
    first = o.margin if np.isfinite(o.margin) and o.margin > 0 else 1.0
    dmax = data.draw(st.sampled_from([None, None, first * 0.5, first * 2.0, first * 7.0]))
    for verify in (True, False):
        case = _loop_case(a, b, kind, dmax, verify)
        out = call(nr.delay_margin, A, B, delta_max=dmax, verify=verify)
        if settle(out, test, "delay_margin", case):
            check_margin(test, o, out.value, case)
    # independent counts at a sampled delay: the oracle's two routes agree, and nrobust agrees with them
    if o.nominal_unstable is None or o.zero_root:
        return
    d = data.draw(st.floats(0.01, 3.0)) * first
    n = unsure_guard(lambda: o.unstable_count(d))
    n_ap = unsure_guard(lambda: o.count_by_argument(d))
    if n is None or n_ap is None:
        return
    assert n == n_ap, f"oracle disagrees with itself at delta = {d}: crossing count {n}, argument principle {n_ap}"
    case = _loop_case(a, b, kind, None, True) + f", delta = {d!r}"
    R = 1.01 * o.rhp_radius()
    F = A + B.shift(d)
    out = call(nr.count_roots, F, (0.0, R, -R, R))
    if settle(out, test, "count_roots", case):
        STATS.claim(int(out.value) == n, test, f"count_roots at delta: {int(out.value)}, truth {n}", case)
    ny = call(nr.plots.nyquist_response, A, B, d)
    if settle(ny, test, "nyquist_response", case) and ny.value.rhp_zeros is not None:
        STATS.claim(ny.value.rhp_zeros == n, test, f"nyquist_response: rhp_zeros {ny.value.rhp_zeros}, truth {n}", case)


def test_loops_against_classical_crossings() -> None:
    """delay_margin (verified and not), its windows and directions, count_roots and Nyquist counts."""
    run(_prop_loops, "loops")


# ============================================================================ 4. k_region on the transport plant
@st.composite
def transport_cases(draw: st.DrawFn) -> tuple[float, float, float, float, float]:
    lam = draw(dyadic(0.25, 4))
    mu = draw(dyadic(0.25, 4))
    q = draw(nonzero_dyadic(0.125, 2))
    rho = draw(dyadic(-2, 2))
    delta_max = 2.0 ** draw(st.integers(-6, 2))
    return lam, mu, q, rho, delta_max


@budget(ci=6, weight=0.3)
@given(transport_cases(), st.data())
def _prop_transport(params: tuple, data: st.DataObject) -> None:
    test = "transport_k_region"
    lam, mu, q, rho, delta_max = params
    STATS.case()
    system = TransportSystem(lam, mu, q, rho)
    truth = transport_k_interval(q, rho)
    kb = truth[1] if truth else 1.0
    Ks = kb * np.linspace(-1.0, 1.0, 7)[1:-1] if truth else np.array([-1.0, 0.0, 1.0])
    tol = kb * 2.0**-14
    case = f"TransportSystem({lam}, {mu}, {q}, {rho}), delta_max = {delta_max}, tol = {tol!r}"
    out = call(nr.k_region, system, delta_max, Ks=Ks, tol=tol)
    if settle(out, test, "k_region", case):
        ivs = out.value.intervals
        if truth is None:
            STATS.claim(len(ivs) == 0, test, f"k_region: {ivs}, truth empty (|rho q| >= 1)", case)
        else:
            ok = len(ivs) == 1 and all(
                abs(e - t) <= 1.001 * tol + 1e-12 * kb and abs(e) <= kb for e, t in zip(ivs[0], truth)
            )
            STATS.claim(ok, test, f"k_region: {ivs}, truth (-{kb!r}, {kb!r}) to {tol:.3g}", case)
    # per-gain margins
    j = data.draw(st.integers(1, 30))
    for K in (kb * (1 - 2.0**-j), -kb * (1 - 2.0**-j), kb * (1 + 2.0**-j), data.draw(st.floats(-2 * kb, 2 * kb))):
        m = transport_margin(q, rho, K)
        if m is None:
            STATS.unsure()
            continue
        gcase = case + f", K = {K!r}"
        out = call(nr.delay_margin, system, ReflectionController(K))
        if settle(out, test, "delay_margin(system, controller)", gcase):
            STATS.claim(out.value.margin == m, test, f"delay_margin: {out.value.margin!r}, truth {m!r}", gcase)
    # the stability chart: no unstable root for |K| < k (any delay); infinitely many for |K| > k, delta > 0
    if truth is None:
        return
    gains = [0.5 * kb, -0.5 * kb, kb * (1 + 2.0**-j)]
    out = call(nr.stability_chart, system, gains, [0.0, 0.5 * delta_max, delta_max])
    if not settle(out, test, "stability_chart", case):
        return
    chart = out.value
    for i, K in enumerate(chart.Ks):
        robust = abs(K) < kb
        for d, v in zip(chart.deltas, chart.values[i]):
            if robust or d > 0:
                want = 0.0 if robust else math.inf
                STATS.claim(v == want, test, f"stability_chart: K = {K!r}, delta = {d!r}: {v!r}, truth {want!r}", case)


def test_transport_k_region() -> None:
    """k_region and per-gain margins of the transport plant against their closed forms."""
    run(_prop_transport, "transport_k_region")


# ============================================================================ 4b. k_region on coupled plants
@st.composite
def coupled_cases(draw: st.DrawFn) -> tuple[float, float, float, float, float, float, float]:
    lam = draw(dyadic(0.5, 2))
    mu = draw(dyadic(0.5, 2))
    sigma_pm = draw(dyadic(-1, 1))
    sigma_mp = draw(dyadic(-1, 1))
    q = draw(nonzero_dyadic(0.5, 1))
    rho = draw(dyadic(-0.875, 0.875)) / abs(q) * 0.875
    delta_max = draw(st.sampled_from([0.05, 0.1, 0.2]))
    return lam, mu, sigma_pm, sigma_mp, q, rho, delta_max


def admissible_verified(system: Any, K: float, delta_max: float, test: str, case: str) -> bool | None:
    """``U_BS2(K)`` stable on ``[0, delta_max]`` by a *verified* delay margin; None on a refusal."""
    out = call(nr.delay_margin, system, ReflectionController(K))
    if not settle(out, test, "delay_margin(system, controller)", case):
        return None
    dm = out.value
    return nominally_stable(dm) and dm.margin > delta_max


@budget(ci=1, weight=0.003)
@given(coupled_cases())
def _prop_coupled_k_region(params: tuple) -> None:
    test = "coupled_k_region"
    *plant, delta_max = params
    system = nr.Hyperbolic2x2(*plant)
    kb = nr.classify(system).k_bound
    if kb <= 0:
        STATS.unsure()
        return
    STATS.case()
    tol = 1e-6 * kb
    case = f"Hyperbolic2x2{tuple(plant)}, delta_max = {delta_max}, tol = {tol!r}"
    out = call(nr.k_region, system, delta_max, Ks=kb * np.linspace(-1.0, 1.0, 9)[1:-1], tol=tol, seconds=600.0)
    if not settle(out, test, "k_region", case):
        return
    region = out.value
    for K, ok in zip(region.Ks, region.admissible):
        got = admissible_verified(system, float(K), delta_max, test, case + f", K = {K!r}")
        if got is not None:
            STATS.claim(
                got == bool(ok), test, f"k_region grid K = {K!r}: admissible {ok}, verified margin says {got}", case
            )
    for lo, hi in region.intervals:
        for end, outward in ((lo, -1.0), (hi, 1.0)):
            beyond = end + outward * 1.01 * tol
            if abs(beyond) >= kb:
                continue  # the paper's bound: no gain beyond it is admissible
            for K, want in ((end, True), (beyond, False)):
                got = admissible_verified(system, K, delta_max, test, case + f", K = {K!r}")
                if got is not None:
                    STATS.claim(
                        got == want,
                        test,
                        f"k_region end {end!r} (to {tol:.3g}): K = {K!r} admissible {got} by verified margin",
                        case,
                    )


@pytest.mark.skipif(not FUZZ, reason="minutes per plant: run by make fuzz (NROBUST_FUZZ_EXAMPLES)")
def test_coupled_k_region() -> None:
    """k_region ends on coupled plants against verified per-gain margins (fuzz budget only)."""
    run(_prop_coupled_k_region, "coupled_k_region")


# ============================================================================ 4c. the PDE itself (exact route)
@st.composite
def constant_plants(draw: st.DrawFn) -> tuple[tuple[float, float, float, float, float, float], tuple]:
    """Plants with random constant coefficients and a controller: ``U_BS2(K)`` mostly, with ``K``
    inside ``|K| < (1 - |rho q|)/|q|`` or outside it, else U_BS, the open loop or the filtered U_BS."""
    lam, mu = draw(st.floats(0.3, 3.0)), draw(st.floats(0.3, 3.0))
    spm, smp = draw(st.just(0.0) | st.floats(-4.0, 4.0)), draw(st.just(0.0) | st.floats(-4.0, 4.0))
    q = draw(st.floats(0.05, 1.0) | st.floats(-1.0, -0.05))
    rho = draw(st.floats(-1.0, 1.0).filter(lambda r: abs(r * q) < 1.0))
    kind = draw(st.sampled_from(["reflection"] * 6 + ["finite", "open", "filtered"]))
    if kind == "reflection":
        kb = (1.0 - abs(rho * q)) / abs(q)
        f = draw(st.floats(-0.95, 0.95) | st.floats(1.05, 3.0) | st.floats(-3.0, -1.05))
        controller: tuple = ("reflection", f * kb)
    elif kind == "filtered":
        controller = ("filtered", draw(st.floats(-2.0, 2.0)), draw(st.floats(0.1, 2.0)))
    else:
        controller = (kind,)
    return (lam, mu, spm, smp, q, rho), controller


def nrobust_controller(spec: tuple) -> Any:
    kind = spec[0]
    if kind == "reflection":
        return ReflectionController(spec[1])
    if kind == "filtered":
        return nr.FilteredController(spec[1], spec[2])
    return nr.FiniteTimeController() if kind == "finite" else nr.OpenLoop()


def ulps(x: float) -> float:
    """Allowance for the oracle's rounding of a proven end to double: a few ulps."""
    return 4 * np.spacing(abs(x)) + 1e-300


def check_pde_margin(test: str, o: PDELoop, dm: Any, case: str) -> None:
    """The proven margin of the exact route against the crossing analysis of the PDE's ``F``."""
    STATS.claim(dm.scope.startswith("the PDE itself"), test, f"delay_margin scope: {dm.scope!r}", case)
    truth = unsure_guard(o.margin)
    if truth is None:
        return
    lo, hi = dm.margin_ball
    if dm.margin == 0.0 or truth == 0.0:
        what = f"delay_margin: proven {dm.margin!r} {dm.margin_ball}, PDE {truth!r}"
        STATS.claim(dm.margin == truth, test, what, case)
    elif math.isinf(dm.margin) or math.isinf(truth):
        STATS.claim(dm.margin == truth, test, f"delay_margin: proven {dm.margin!r}, PDE {truth!r}", case)
    else:
        STATS.claim(
            lo - ulps(lo) <= truth <= hi + ulps(hi),
            test,
            f"delay_margin: margin_ball {dm.margin_ball} misses the PDE's margin {truth!r}",
            case,
        )


def check_pde_abscissa(test: str, o: PDELoop, F: QuasiPolynomial, delta: float, case: str) -> None:
    """No zero of the PDE's ``F`` right of the proven upper end; the reported root is one of ``F``."""
    out = call(nr.spectral_abscissa, F, rigorous=True)
    if not settle(out, test, "spectral_abscissa(rigorous=True)", case):
        return
    sa = out.value
    if sa.value_bracket is None:
        STATS.refusal(test)
        return
    hi = float(sa.value_bracket[1])
    if not np.isfinite(hi):  # no zero at all (-inf): any box must be empty; +inf claims nothing
        if hi > 0:
            return
        hi = -2.0
    gap = 1e-3 * (1.0 + abs(hi))
    y = 10.0 + (abs(sa.root.imag) if sa.root is not None else 0.0)
    found = unsure_guard(lambda: o.roots_near((hi - 1.0, hi + 2.0, 0.0, y), delta))
    if found is not None:
        right = [r for r in found if r.real > hi + ulps(hi) + 1e-12 * (1 + abs(r))]
        # a secant iteration can stall far left where F is flat at the working precision: a root that
        # would contradict is confirmed by |F| against the size of its terms first
        confirmed = [r for r in right if unsure_guard(partial(o.is_zero, r, delta))]
        if len(confirmed) < len(right):
            STATS.unsure()
        STATS.claim(
            not confirmed, test, f"spectral_abscissa: bracket ends at {hi!r}, PDE root(s) {confirmed[:3]}", case
        )

    def box_count() -> int:
        x0 = hi + gap
        R = o.far_field(x0, delta, cap=400.0)
        return o.count_in_box((x0, max(R, x0 + 1.0), -R, R), delta)

    n = unsure_guard(box_count)
    if n is not None:
        STATS.claim(n == 0, test, f"spectral_abscissa: {n} PDE roots right of {hi + gap!r} (bracket {hi!r})", case)
    if sa.root is not None and sa.root_box is not None:
        r = unsure_guard(lambda: complex(o.polish(sa.root, delta)))
        if r is not None:
            x0, x1, y0, y1 = sa.root_box
            slack = 1e-14 * (1 + abs(r))
            inside = x0 - slack <= r.real <= x1 + slack and y0 - slack <= abs(r.imag) <= y1 + slack
            STATS.claim(
                inside and abs(r - sa.root) <= 1e-6 * (1 + abs(r)),
                test,
                f"spectral_abscissa: root {sa.root!r} (box {sa.root_box}), PDE root {r!r}",
                case,
            )


def check_pde_roots(test: str, o: PDELoop, F: QuasiPolynomial, delta: float, box: tuple, case: str) -> None:
    """Each proven box of ``find_roots(rigorous=True)`` holds a root of the PDE's ``F``."""
    out = call(nr.find_roots, F, box, rigorous=True)
    if not settle(out, test, "find_roots(rigorous=True)", case):
        return
    rs = out.value
    for z, b, proof in zip(rs.roots, rs.boxes, rs.proofs):
        if proof != "krawczyk":
            STATS.unsure()  # a cluster: the secant iteration is not the oracle for it
            continue
        r = unsure_guard(partial(o.polish, complex(z), delta))
        if r is None:
            continue
        r = complex(r)
        slack = 1e-14 * (1 + abs(r))
        STATS.claim(
            b[0] - slack <= r.real <= b[1] + slack and b[2] - slack <= r.imag <= b[3] + slack,
            test,
            f"find_roots: proven box {tuple(b)} of {z!r}, PDE root {r!r}",
            case + f", box = {box}",
        )


@budget(ci=3, weight=0.15)
@given(constant_plants(), st.data())
def _prop_constant_plants(plant: tuple, data: st.DataObject) -> None:
    test = "pde_exact_route"
    args, spec = plant
    STATS.case()
    case = f"Hyperbolic2x2{args}, {spec}"
    lam, mu, spm, smp, q, rho = args
    o = unsure_guard(lambda: PDELoop(lam, mu, spm, smp, q, rho, spec))
    if o is None:
        return
    system, controller = nr.Hyperbolic2x2(*args), nrobust_controller(spec)
    out = call(nr.delay_margin, system, controller, rigorous=True)
    dm = out.value if settle(out, test, "delay_margin(rigorous=True)", case) else None
    if dm is not None:
        check_pde_margin(test, o, dm, case)
    first = dm.margin if dm is not None and 0.0 < dm.margin < math.inf else 1.0
    delta = data.draw(st.sampled_from([0.0, 0.5, 1.0, 1.5])) * first
    dcase = case + f", delta = {delta!r}"
    F = nr.characteristic(system, controller, delta)
    check_pde_abscissa(test, o, F, delta, dcase)
    x = data.draw(st.floats(-2.0, 0.5))
    box = (x, x + data.draw(st.floats(0.3, 2.0)), -0.5, data.draw(st.floats(2.0, 20.0)))
    check_pde_roots(test, o, F, delta, box, dcase)


def test_constant_plants_against_the_pde() -> None:
    """Proven margins, abscissae and root boxes of the exact route against the PDE's Laplace solution."""
    run(_prop_constant_plants, "pde_exact_route")


# ============================================================================ 4d. varying coefficients (the PDE itself)
@st.composite
def profiles(draw: st.DrawFn, scale: float) -> Profile:
    """A coefficient: a constant given as a function, ``c0 + c1 sin(w x + phi)`` or ``c0 e^{w x}``."""
    kind = draw(st.sampled_from(["const", "sin", "sin", "exp"]))
    c0 = draw(st.floats(-scale, scale))
    if kind == "const":
        return Profile("sin", c0)
    if kind == "sin":
        return Profile(
            "sin", c0, draw(st.floats(-scale / 2, scale / 2)), draw(st.floats(0.5, 4.0)), draw(st.floats(0, 3))
        )
    return Profile("exp", c0, 0.0, draw(st.floats(-1.5, 1.5)))


@st.composite
def varying_plants(draw: st.DrawFn) -> tuple[Any, VaryingPDELoop, Any, str]:
    """The paper's plant with varying couplings, or a general plant with varying ``a, b, c, d`` and a
    length ``L``, with U_BS2(K) (``K`` inside or outside ``(1 - |rho~ q~|)/|q~|``), U_BS, the open loop
    or ``U = k u(t, L)``; returned with its ODE oracle."""
    zero = Profile("sin", 0.0)
    q = draw(st.floats(0.1, 1.0) | st.floats(-1.0, -0.1))
    rho = draw(st.floats(-1.0, 1.0))
    # a quarter of the plants: every coefficient a constant given as a number (the closed-form route of constant
    # coefficients, the general plant's normal form in closed form), checked against the same ODE oracle
    numbers = draw(st.integers(0, 3)) == 0

    def given(p: Profile) -> Any:
        return p.c0 if numbers else p.numpy()

    def drawn(scale: float) -> Profile:
        return Profile("sin", draw(st.floats(-scale, scale))) if numbers else draw(profiles(scale))

    if draw(st.booleans()):
        lam, mu, length = draw(st.floats(0.5, 3.0)), draw(st.floats(0.5, 3.0)), 1.0
        coefs = {"a": zero, "b": drawn(1.5), "c": drawn(1.5), "d": zero}
        plant = nr.Hyperbolic2x2(lam, mu, given(coefs["b"]), given(coefs["c"]), q, rho)
        q_normal = q
    else:
        lam, mu, length = draw(st.floats(0.5, 2.0)), draw(st.floats(0.5, 2.0)), draw(st.floats(0.5, 2.0))
        coefs = {"a": drawn(0.6), "b": drawn(1.5), "c": drawn(1.5), "d": drawn(0.6)}
        plant = nr.GeneralHyperbolic2x2(
            lam,
            mu,
            *(given(coefs[k]) for k in "abcd"),
            q,
            rho,
            length=length,  # type: ignore[arg-type]
        )
        q_normal = plant.normal_form().system.q
    o = VaryingPDELoop(lam, mu, length, coefs, q, rho, ("open",), q_normal)
    principal = float(abs(o.principal))
    assume(principal < 0.95)
    kind = draw(st.sampled_from(["reflection"] * 4 + ["finite", "open", "state"]))
    if kind == "reflection":
        f = draw(st.floats(-0.95, 0.95) | st.floats(1.05, 2.0) | st.floats(-2.0, -1.05))
        spec: tuple = ("reflection", f * (1.0 - principal) / abs(q_normal))
        controller: Any = ReflectionController(spec[1])
    elif kind == "state":
        spec = ("state", -rho + draw(st.floats(-0.3, 0.3)))
        controller = nr.StateFeedback(spec[1])
    else:
        spec = (kind,)
        controller = nr.FiniteTimeController() if kind == "finite" else nr.OpenLoop()
    o.controller = spec
    form = "numbers" if numbers else "functions"
    what = (
        f"{type(plant).__name__}(lam={lam!r}, mu={mu!r}, L={length!r}, {coefs} as {form}, q={q!r}, rho={rho!r}), {spec}"
    )
    return plant, o, controller, what


def _inside_ball(ball: Any, value: complex, slack: float) -> bool:
    re, im = ball.real, ball.imag
    return bool(
        float(re.lower()) - slack <= value.real <= float(re.upper()) + slack
        and float(im.lower()) - slack <= value.imag <= float(im.upper()) + slack
    )


@budget(ci=2, weight=0.05)
@given(varying_plants(), st.data())
def _prop_varying_plants(case: tuple, data: st.DataObject) -> None:
    test = "pde_varying"
    plant, o, controller, what = case
    STATS.case()
    flint = pytest.importorskip("flint")
    if "as numbers" in what:  # constant coefficients as numbers: the closed-form loops of the exact route
        out = call(
            lambda: (nr.loop_factors(plant, nr.OpenLoop())[0], -nr.loop_factors(plant, nr.StateFeedback(1.0))[1])
        )
        if not settle(out, test, "loop_factors", what):
            return
        characteristic, u_factor = out.value
    else:
        if not has_varying_proof(plant):
            STATS.refusal(test)
            return
        out = call(varying_proof, plant)
        if not settle(out, test, "varying_proof", what):
            return
        characteristic, u_factor = out.value.characteristic, out.value.u_factor
    for _ in range(2):
        s = complex(data.draw(st.floats(-0.4, 1.0)), data.draw(st.floats(0.0, 25.0)))
        truth = unsure_guard(lambda s=s: o.factors_mp(s))
        if truth is None:
            continue
        A, _, u = (complex(v) for v in truth)
        # tau and the principal gains are doubles rounded from their values (the scope says so): a
        # few ulps times |s| tau and the gains' size; the ODE's 20 digits
        grow = math.exp(o.tau * max(0.0, -s.real))
        slack = (1e-17 + 8 * 2.0**-52 * (1 + abs(s) * o.tau)) * (2 + abs(A) + abs(u)) * grow
        for name, F, value in (("open loop", characteristic, A), ("u(L, s)", u_factor, u)):
            ball = ball_eval(F, flint.acb(s.real, s.imag))
            STATS.claim(
                _inside_ball(ball, value, slack), test, f"{name} at s = {s!r}: ball {ball} misses {value!r}", what
            )
    if o.controller[0] == "open" or loop_route(plant, controller) != "exact":
        return  # the open loop does not depend on the delay
    out = call(nr.delay_margin, plant, controller, delta_max=20.0, rigorous=True)
    if not settle(out, test, "delay_margin(rigorous=True)", what):
        return
    dm = out.value
    STATS.claim(dm.scope.startswith("the PDE itself"), test, f"delay_margin scope: {dm.scope!r}", what)
    if dm.margin == 0.0 or dm.margin_ball is None:
        return
    lo, hi = dm.margin_ball
    band = min(max(1.5 * (dm.omega or 0.0), 20.0 / o.tau), 40.0 / o.tau)
    if math.isfinite(dm.margin):
        found = unsure_guard(lambda: o.crossing_near(dm.omega))
        if found is not None:
            slack = ulps(hi) + 1e-15 * (1 + found[1])  # the rounded tau and gains, as above
            STATS.claim(
                lo - slack <= found[1] <= hi + slack,
                test,
                f"delay_margin: ball {dm.margin_ball} misses the PDE's crossing delay {found[1]!r} at w = {found[0]!r}",
                what,
            )
    crossings = unsure_guard(lambda: o.crossings_in_band(band))
    if crossings is not None:
        early = [c for c in crossings if c[1] < lo - 1e-8 * (1 + lo)]  # the double-precision scan's accuracy
        STATS.claim(
            not early,
            test,
            f"delay_margin: ball {dm.margin_ball}, the PDE crosses at (w, delta) = {early[:3]} (band {band:.3g})",
            what,
        )


def test_varying_plants_against_the_pde() -> None:
    """Proofs about plants with varying coefficients against the Laplace-domain ODE of the original plant."""
    run(_prop_varying_plants, "pde_varying")


# ============================================================================ 4e. varying speeds (the PDE itself)
@st.composite
def speeds(draw: st.DrawFn, length: float) -> Speed:
    """A speed on ``[0, L]``: ``c0 (1 + e1 x + e2 x^2)`` or ``c0 e^{e1 x}``, at least ``0.4 c0`` there."""
    c0 = draw(st.floats(0.5, 3.0))
    if draw(st.booleans()):
        return Speed("exp", c0, draw(st.floats(-1.0, 1.0)) / length)
    e1, e2 = draw(st.floats(-0.3, 1.0)), draw(st.just(0.0) | st.floats(-0.3, 0.6))
    return Speed("poly", c0, e1 / length, e2 / length**2)


@st.composite
def varying_speed_plants(draw: st.DrawFn) -> tuple[Any, VaryingSpeedPDELoop, Any, str]:
    """A general plant whose speeds vary (at a constant ratio or not) with varying ``a, b, c, d``, a
    length and a time unit, closed by ``U = k u(t, L)`` or (constant ratio) U_BS2(K), ``K`` inside or
    outside ``(1 - |rho~ q~|)/|q~|``; returned with its ODE oracle."""
    length, time_unit = draw(st.floats(0.5, 2.0)), draw(st.floats(0.5, 3.0))
    lam = draw(speeds(length))
    mu = Speed("ratio", draw(st.floats(0.3, 3.0)), of=lam) if draw(st.booleans()) else draw(speeds(length))
    coefs = {"a": draw(profiles(0.4)), "b": draw(profiles(1.5)), "c": draw(profiles(1.5)), "d": draw(profiles(0.4))}
    q = draw(st.floats(0.1, 1.0) | st.floats(-1.0, -0.1))
    rho = draw(st.floats(-1.0, 1.0))
    plant = nr.GeneralHyperbolic2x2(
        lam.numpy(),
        mu.numpy(),
        *(coefs[k].numpy() for k in "abcd"),
        q,
        rho,
        length=length,  # type: ignore[arg-type]
        time_unit=time_unit,
    )
    o = VaryingSpeedPDELoop(lam, mu, length, coefs, q, rho, ("open",), time_unit=time_unit)
    principal = float(abs(o.principal))
    assume(principal < 0.95)
    if mu.of is not None and draw(st.booleans()):
        o.q_normal = plant.normal_form().system.q  # K is read in the normal form's coordinates
        f = draw(st.floats(-0.95, 0.95) | st.floats(1.05, 2.0) | st.floats(-2.0, -1.05))
        spec: tuple = ("reflection", f * (1.0 - principal) / abs(o.q_normal))
        controller: Any = ReflectionController(spec[1])
    else:
        spec = ("state", -rho + draw(st.floats(-0.3, 0.3)))
        controller = nr.StateFeedback(spec[1])
    o.controller = spec
    what = (
        f"GeneralHyperbolic2x2(lam={lam}, mu={mu}, {coefs}, q={q!r}, rho={rho!r}, length={length!r}, "
        f"time_unit={time_unit!r}), {spec}"
    )
    return plant, o, controller, what


def speed_factor(assumption: str) -> float:
    """The bound on the factor of the speeds proven, from ``VaryingProof.assumption`` (0: none stated)."""
    found = re.search(r"a factor within ([0-9.eE+-]+) of 1", assumption)
    return float(found.group(1)) if found else 0.0


@budget(ci=1, weight=0.05)
@given(varying_speed_plants(), st.tuples(st.floats(-0.4, 1.0), st.floats(0.0, 25.0), st.floats(0.0, 25.0)))
@example(
    (
        nr.GeneralHyperbolic2x2(
            Speed("poly", 1.2, 0.4).numpy(),
            Speed("exp", 0.8, 0.3).numpy(),
            0.0,
            Profile("exp", 0.8, 0.0, 0.5).numpy(),
            Profile("sin", 0.5, 0.3, 2.0, 0.5).numpy(),
            0.0,
            0.7,
            0.4,
            length=1.3,
            time_unit=2.0,
        ),
        VaryingSpeedPDELoop(
            Speed("poly", 1.2, 0.4),
            Speed("exp", 0.8, 0.3),
            1.3,
            {
                "a": Profile("sin", 0.0),
                "b": Profile("exp", 0.8, 0.0, 0.5),
                "c": Profile("sin", 0.5, 0.3, 2.0, 0.5),
                "d": Profile("sin", 0.0),
            },
            0.7,
            0.4,
            ("state", -0.6),
            time_unit=2.0,
        ),
        nr.StateFeedback(-0.6),
        "the fixed example: lam = 1.2 (1 + 0.4 x), mu = 0.8 e^{0.3 x}, L = 1.3, time_unit = 2, U = -0.6 u(t, L)",
    ),
    (-0.3, 4.0, 15.0),
)
def _prop_varying_speeds(case: tuple, points: tuple[float, float, float]) -> None:
    test = "pde_varying_speeds"
    plant, o, controller, what = case
    STATS.case()
    flint = pytest.importorskip("flint")
    # a refusal after the largest kernel (4096 pieces) takes about 5 s of CPU: wall time on a loaded machine
    out = call(varying_proof, plant, seconds=max(EXAMPLE_SECONDS, 60.0))
    if not settle(out, test, "varying_proof", what):
        return
    proof = out.value
    factor = speed_factor(proof.assumption)
    for s in (complex(0.0, points[1]), complex(points[0], points[2])):  # on and off the imaginary axis
        truth = unsure_guard(lambda s=s: o.factors_mp(s))
        if truth is None:
            continue
        A, _, u = (complex(v) for v in truth)
        # tau and the principal gains are doubles rounded from their values, the speeds proven are the
        # plant's times a factor within `factor` of 1 (the scope says so): relative changes of the gains
        # (a few ulps) and of the phases (|s| tau times the factor); the ODE's 25 digits
        grow = math.exp(o.tau * max(0.0, -s.real))
        slack = (1e-20 + 8 * 2.0**-52 * (1 + abs(s) * o.tau) + abs(s) * o.tau * factor) * (2 + abs(A) + abs(u)) * grow
        for name, F, value in (("open loop", proof.characteristic, A), ("u(L, s)", proof.u_factor, u)):
            ball = ball_eval(F, flint.acb(s.real, s.imag))
            STATS.claim(
                _inside_ball(ball, value, slack), test, f"{name} at s = {s!r}: ball {ball} misses {value!r}", what
            )
    if loop_route(plant, controller) != "exact":
        STATS.refusal(test)
        return
    out = call(nr.delay_margin, plant, controller, delta_max=20.0, rigorous=True)
    if not settle(out, test, "delay_margin(rigorous=True)", what):
        return
    dm = out.value
    STATS.claim(dm.scope.startswith("the PDE itself"), test, f"delay_margin scope: {dm.scope!r}", what)
    out = call(nr.delay_margin, plant, controller, delta_max=20.0)
    if not settle(out, test, "delay_margin", what) or out.value.omega is None or not 0.0 < out.value.margin < 20.0:
        return
    found = unsure_guard(lambda: o.crossing_near(out.value.omega))  # the PDE's crossing the float margin found
    if found is None or dm.margin_ball is None or found[1] > 20.0:
        return
    lo, hi = dm.margin_ball
    slack = ulps(hi) + (1e-15 + factor) * (1 + found[1])  # the rounded tau and gains, the speeds' factor
    STATS.claim(
        lo - slack <= found[1] <= hi + slack,
        test,
        f"delay_margin: ball {dm.margin_ball} misses the PDE's crossing delay {found[1]!r} at w = {found[0]!r} "
        f"(float margin {out.value.margin!r})",
        what,
    )


def test_varying_speeds_against_the_pde() -> None:
    """Proofs about plants whose speeds and coefficients vary against the Laplace-domain ODE of the plant."""
    run(_prop_varying_speeds, "pde_varying_speeds")


# ============================================================================ 4f. n + m plants (the PDE itself)
@st.composite
def nplusm_plants(draw: st.DrawFn) -> tuple[tuple, tuple]:
    """``n + m`` plants (``n`` in 1..2, ``m = 1`` mostly, else 2) with distinct speeds, couplings small to
    moderate (the diagonal zero or not) and a gain ``K``; ``R`` and ``K`` scaled so that a bound of
    ``gamma_0`` of the delayed principal part (the row sums of ``V^{-1} (|R| + |K|) |U Q|``, groups of one
    speed each) is a drawn value below 1. Returns the plant's arguments and ``K``."""
    n, m = draw(st.integers(1, 2)), draw(st.sampled_from([1, 1, 1, 2]))
    lam = draw(st.lists(st.floats(0.4, 3.0), min_size=n, max_size=n))
    mu = draw(st.lists(st.floats(0.4, 3.0), min_size=m, max_size=m))
    assume(all(abs(a - b) > 0.05 for a, b in itertools.combinations(lam, 2)))
    assume(all(abs(a - b) > 0.05 for a, b in itertools.combinations(mu, 2)))
    scale = draw(st.sampled_from([0.3, 1.0, 2.0]))
    entry = st.just(0.0) | st.floats(-scale, scale).filter(lambda x: abs(x) > 1e-3)
    sigma = np.array([[draw(entry) for _ in range(n + m)] for _ in range(n + m)])
    if draw(st.booleans()):
        np.fill_diagonal(sigma, 0.0)
    reflection = st.floats(0.05, 1.0) | st.floats(-1.0, -0.05)  # as in constant_plants: chains in view
    q = np.array([[draw(reflection) for _ in range(m)] for _ in range(n)])
    r = np.array([[draw(reflection) for _ in range(n)] for _ in range(m)])
    k = np.array([[draw(st.just(0.0) | st.floats(-1.5, 1.5)) for _ in range(n)] for _ in range(m)])
    u = np.exp(np.diag(sigma)[:n] / np.array(lam))[:, None] * np.abs(q)  # |U_a Q|
    v_inv = np.exp(np.diag(sigma)[n:] / np.array(mu))[:, None]
    rows = (v_inv * (np.abs(r) + np.abs(k)) @ u).sum(axis=1)
    gamma = float(rows.max())
    target = draw(st.floats(0.05, 0.9))
    if gamma > target:
        r, k = r * (target / gamma), k * (target / gamma)
    return (lam, mu, sigma.tolist(), q.tolist(), r.tolist()), k.tolist()


def check_nplusm_margin(test: str, o: NPlusMLoop, dm: Any, what: str, case: str) -> bool:
    """A delay margin of an ``n + m`` loop against the oracle's crossings: the oracle's crossing from the
    reported ``(omega, margin)`` lies in the claimed interval (``margin_bracket``, or ``margin +- error``),
    and the scan of a band finds no crossing below its lower end. True iff the margin claims an unstable
    delay-free loop (checked by the caller on the abscissa)."""
    if dm.margin == 0.0:
        # gamma_0 < 1 by construction: a margin 0 must come from an unstable delay-free loop
        unstable = bool(dm.nominal_unstable)
        STATS.claim(unstable, test, f"{what}: margin 0 with nominal_unstable = {dm.nominal_unstable}", case)
        return unstable
    band = min(max(1.5 * (dm.omega or 0.0), 20.0 / o.tau), 40.0 / o.tau)
    if math.isinf(dm.margin):
        crossings = unsure_guard(lambda: o.crossings_in_band(band))
        if crossings is not None:
            STATS.claim(not crossings, test, f"{what}: margin inf, the PDE crosses at {crossings[:3]}", case)
        return False
    if dm.margin_bracket is not None:
        lo, hi = dm.margin_bracket
        slack = ulps(hi)
    elif dm.error is not None:
        lo, hi, slack = dm.margin - dm.error, dm.margin + dm.error, ulps(dm.margin)
    else:
        STATS.unsure()  # no stated accuracy: nothing to check the digits against
        return False
    found = unsure_guard(lambda: o.crossing_near(dm.omega, dm.margin))
    if found is not None:
        STATS.claim(
            lo - slack <= found[1] <= hi + slack,
            test,
            f"{what}: [{lo!r}, {hi!r}] misses the PDE's crossing delay {found[1]!r} at w = {found[0]!r}",
            case,
        )
    crossings = unsure_guard(lambda: o.crossings_in_band(band))
    if crossings is not None:
        early = [c for c in crossings if c[1] < lo - 1e-8 * (1 + lo)]  # the double-precision scan's accuracy
        where = f"the PDE crosses at (w, delta) = {early[:3]} (band {band:.3g})"
        STATS.claim(not early, test, f"{what}: lower end {lo!r}, {where}", case)
    return False


def check_nplusm_abscissa(test: str, o: NPlusMLoop, sa: Any, delta: float, unstable: bool, case: str) -> None:
    """The proven abscissa of an ``n + m`` loop: the oracle's root polished from the reported root lies in the
    proven box and in ``value_bracket``; no oracle root found right of the proven upper bound; a loop claimed
    unstable (``unstable``, ``delta = 0``) has the oracle's root in ``Re s > 0``."""
    hi = float(sa.upper_bound)
    if sa.root is not None and sa.root_box is not None:
        r = unsure_guard(lambda: complex(o.polish(sa.root, delta)))
        if r is not None:
            x0, x1, y0, y1 = sa.root_box
            lo_b, hi_b = sa.value_bracket
            slack = 1e-14 * (1 + abs(r))
            inside = x0 - slack <= r.real <= x1 + slack and y0 - slack <= abs(r.imag) <= y1 + slack
            STATS.claim(
                inside and lo_b - slack <= r.real <= hi_b + slack,
                test,
                f"proven_abscissa: root {sa.root!r} (box {sa.root_box}, bracket {sa.value_bracket}), PDE root {r!r}",
                case,
            )
            if unstable:
                STATS.claim(r.real > 0, test, f"nominal_unstable claimed, the PDE's rightmost root {r!r}", case)
    elif unstable:
        STATS.contradiction(test, f"nominal_unstable claimed, proven abscissa {sa!r} has no root", case)
    y = 10.0 + (abs(sa.root.imag) if sa.root is not None else 0.0)
    found = unsure_guard(lambda: o.roots_near((hi, hi + 1.5, 0.0, y), delta, right_of=hi))
    if found is not None:
        right = [r for r in found if r.real > hi + ulps(hi) + 1e-12 * (1 + abs(r))]
        STATS.claim(not right, test, f"proven_abscissa: upper bound {hi!r}, PDE root(s) {right[:3]}", case)


@budget(ci=2, weight=0.2)
@given(nplusm_plants(), st.data())
def _prop_nplusm_plants(plant: tuple, data: st.DataObject) -> None:
    test = "pde_nplusm"
    args, k = plant
    STATS.case()
    case = f"NPlusMSystem{args}, K = {k}"
    pytest.importorskip("flint")
    system = NPlusMSystem(*args)
    o = NPlusMLoop(*args, k)
    unstable, first = False, 1.0
    if system.m == 1:
        out = call(nplusm_delay_margin, system, k, rigorous=True)
        if settle(out, test, "nplusm_delay_margin(rigorous=True)", case):
            dm = out.value
            proven = dm.rigorous and (dm.margin_bracket is not None or dm.margin in (0.0, math.inf))
            STATS.claim(proven, test, f"nplusm_delay_margin(rigorous=True): no proven bracket in {dm!r}", case)
            unstable = check_nplusm_margin(test, o, dm, "nplusm_delay_margin(rigorous=True)", case)
            first = dm.margin if 0.0 < dm.margin < math.inf else first
        out = call(nplusm_delay_margin, system, k)
        if settle(out, test, "nplusm_delay_margin", case):
            unstable |= check_nplusm_margin(test, o, out.value, "nplusm_delay_margin", case)
    out = call(multi_actuator_delay_margin, system, k)
    if settle(out, test, "multi_actuator_delay_margin", case):
        dm = out.value
        unstable |= check_nplusm_margin(test, o, dm, "multi_actuator_delay_margin", case)
        first = dm.margin if system.m > 1 and 0.0 < dm.margin < math.inf else first
    delta = 0.0 if unstable else data.draw(st.sampled_from([0.0, 0.5, 1.0, 1.5])) * first
    dcase = case + f", delta = {delta!r}"
    # a work bound: near a chain the proven far field can need a rectangle of size 1e3 (tens of seconds);
    # the refusal is counted
    out = call(NPlusMCharacteristic(system, k, delta).proven_abscissa, max_evals=200_000)
    if settle(out, test, "proven_abscissa", dcase):
        check_nplusm_abscissa(test, o, out.value, delta, unstable, dcase)


def test_nplusm_plants_against_the_pde() -> None:
    """Proven and certified margins and proven abscissae of ``n + m`` plants against the Laplace solution
    of the PDE at 30 digits."""
    run(_prop_nplusm_plants, "pde_nplusm")


# ============================================================================ 5. bad input
NAN, INF = float("nan"), float("inf")
JUNK: list[Any] = [None, "1", object(), {"a": 1}, 1 + 1j, True, [1.0, 2.0]]

#: tag -> (values that must be refused, values that may be accepted but must not give NaN)
VALUES: dict[str, tuple[list[Any], list[Any]]] = {
    "real": ([*JUNK, NAN, INF, -INF], [-1.0, 0.0, 1e300, -1e300, 5e-324]),
    "pos": ([*JUNK, NAN, INF, -INF, -1.0, 0.0], [1e300, 5e-324]),
    "nonneg": ([*JUNK, NAN, INF, -INF, -1.0], [0.0, 1e300, 5e-324]),
    "pos_or_none": ([v for v in JUNK if v is not None] + [NAN, -INF, -1.0, 0.0], [None, INF, 1e300, 5e-324]),
    "int": ([None, "3", 2.5, NAN, True, -1, 0, [3]], [10**9, 10**18]),
    "int0": ([None, "3", 2.5, NAN, True, -1, [3]], [0, 10**9]),
    # an int whose None is a documented default (simulate's cells: the scheme's default)
    "int_or_none": (["3", 2.5, NAN, True, -1, 0, [3]], [None, 10**9, 10**18]),
    "region": (
        [
            None,
            (),
            (0.0, 1.0, 0.0),
            (1.0, 0.0, 0.0, 1.0),
            (0.0, 1.0, 1.0, 0.0),
            (NAN, 1.0, 0.0, 1.0),
            (0.0, INF, 0.0, 1.0),
            "abcd",
            (0.0, 1.0, 0.0, 1.0, 2.0),
            ("a", "b", "c", "d"),
        ],
        [(-1e300, 1e300, -1e300, 1e300), (0.0, 1e-300, 0.0, 1e-300), (-1e6, 1e6, -1e6, 1e6)],
    ),
    "region_or_none": (
        [(), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0, 1.0), (NAN, 1.0, 0.0, 1.0), "abcd", (0.0, INF, 0.0, 1.0)],
        [None, (-1e6, 1e6, -1e6, 1e6)],
    ),
    "qp": ([None, "s", [[1.0]], object(), 1.0], []),
    "F": ([None, "s", [[1.0]], object(), 1.0, QuasiPolynomial([[0.0]], [0.0])], []),
    "qp_or_number": ([None, "s", [[1.0]], object(), NAN, INF, True], [0.0, -1.0, 1e300]),
    "coefs": (
        [[], [[]], [["a"]], [[NAN]], [[INF]], [[1.0, None]], "abc", None, [[True]], [[1.0], [2.0], [3.0]]],
        [[[1e300, 1.0], [1.0]], [[5e-324, 1.0], [0.5]], [[1.0, 1.0], [1e300]]],
    ),
    "delays": (
        [[NAN, 1.0], [-1.0, 1.0], ["a", "b"], None, [], [INF, 1.0], [True, False], [0.0], "01"],
        [[0.0, 1e300], [0.0, 5e-324], [0.0, 1e6]],
    ),
    "pair": (
        [[NAN, 1.0], ["a", "b"], None, [], [INF, 1.0], [True, False], "ab", [1.0, None]],
        [[1e300, 1.0], [5e-324, 1.0]],
    ),
    "nodes": (
        [[NAN, 0.5, 1.0], [-1.0, 0.5, 1.0], ["a", "b", "c"], None, [], [0.0, INF, 1.0], [1.0, 0.5, 0.0], "abc"],
        [[0.0, 0.5, 1e300], [0.0, 5e-324, 1e-300]],
    ),
    "values": ([[NAN, 1.0, 1.0], ["a", "b", "c"], None, [], [1.0, INF, 1.0], [1.0, 1.0]], [[1e300] * 3, [1j] * 3]),
    "system": ([None, "paper", 1.0, object(), {"lam": 1.0}], []),
    "controller": ([None, "K", 0.5, object()], []),
    "choice": (["nope", None, 1, ""], []),
    "grid": ([[], [NAN], [INF], "abc", None, [[1.0, 2.0], [3.0]], [True, False]], [[1e300], [-1e300], [0.0]]),
    # a grid whose None is the documented default (k_region's Ks)
    "grid_or_none": ([[], [NAN], [INF], "abc", [[1.0, 2.0], [3.0]], [True, False]], [None, [1e300], [-1e300], [0.0]]),
    "state": ([None, "x", 1j, NAN, [NAN] * 3, lambda x: np.full_like(x, np.nan)], [0.0, lambda x: 1e300 + 0 * x]),
    "seeds": ([["a"], [NAN], "abc"], [[], [1e300 + 0j]]),
    "omega": ([[], [NAN], "abc", None, [[1.0], [2.0, 3.0]]], [[1e300], [0.0], [-1.0]]),
}


@dataclass(frozen=True)
class Spec:
    """A public function, a cheap valid call, and the tags of the arguments to corrupt
    (an int: a positional argument; a str: a keyword argument)."""

    name: str
    fn: Callable[..., Any]
    args: tuple
    kwargs: dict = field(default_factory=dict)
    params: tuple[tuple[int | str, str], ...] = ()
    extra_bad: dict = field(default_factory=dict)

    def param_name(self, p: int | str) -> str:
        if isinstance(p, str):
            return p
        try:
            return list(inspect.signature(self.fn).parameters)[p]
        except (TypeError, ValueError, IndexError):
            return f"argument {p}"


F0 = QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1.0])  # s + 1 + 0.5 e^{-s}
A0, B0 = QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[2.0]], [0.0])
T0 = TransportSystem(1.0, 2.0, 0.5, 0.8)
C0 = ReflectionController(0.2)
N0 = DistributedDelay([0.0, 0.5, 1.0], [1.0, 0.5, 0.25])


def _sin(x: np.ndarray) -> np.ndarray:
    return np.sin(np.pi * x)


SPECS: list[Spec] = [
    Spec("QuasiPolynomial", QuasiPolynomial, ([[1.0, 1.0], [0.5]], [0.0, 1.0]), params=((0, "coefs"), (1, "delays"))),
    Spec(
        "DistributedDelay",
        DistributedDelay,
        ([0.0, 0.5, 1.0], [1.0, 0.5, 0.25], [1.0]),
        params=((0, "nodes"), (1, "values"), (2, "coefs"), ("moment", "int0"), ("interpolation", "choice")),
        kwargs={"moment": 0, "interpolation": "linear"},
    ),
    Spec("DifferenceOperator", nr.DifferenceOperator, ([1.0, -0.5], [0.0, 1.0]), params=((0, "pair"), (1, "delays"))),
    Spec(
        "count_roots",
        nr.count_roots,
        (F0, (-2.0, 1.0, -5.0, 5.0)),
        {"max_evals": 2_000_000, "max_shifts": 4},
        ((0, "F"), (1, "region"), ("max_evals", "int"), ("max_shifts", "int0")),
    ),
    Spec(
        "find_roots",
        nr.find_roots,
        (F0, (-2.0, 1.0, -5.0, 5.0)),
        {"cluster_tol": 1e-6, "seeds": None, "method": "auto", "max_evals": 5_000_000},
        (
            (0, "F"),
            (1, "region"),
            ("cluster_tol", "pos"),
            ("seeds", "seeds"),
            ("method", "choice"),
            ("max_evals", "int"),
        ),
    ),
    Spec(
        "spectral_abscissa",
        nr.spectral_abscissa,
        (F0,),
        {"region": None, "im_max": None, "cluster_tol": 1e-6},
        ((0, "F"), ("region", "region_or_none"), ("im_max", "pos_or_none"), ("cluster_tol", "pos")),
    ),
    Spec(
        "delay_margin(A, B)",
        nr.delay_margin,
        (A0, B0),
        {"delta_max": None, "max_evals": 2_000_000},
        ((0, "qp_or_number"), (1, "qp_or_number"), ("delta_max", "pos_or_none"), ("max_evals", "int")),
    ),
    Spec(
        "delay_margin(system, controller)",
        nr.delay_margin,
        (T0, C0),
        {"delta_max": None},
        ((0, "system"), (1, "controller"), ("delta_max", "pos_or_none")),
    ),
    Spec(
        "crossing_frequencies",
        nr.crossing_frequencies,
        (A0, B0),
        {"max_evals": 2_000_000},
        ((0, "qp"), (1, "qp"), ("max_evals", "int")),
    ),
    Spec("root_free_region", nr.root_free_region, (F0, 0.0), params=((0, "F"), (1, "real"))),
    Spec("l1_modulus", nr.l1_modulus, (N0, [0.1, 0.2]), params=((0, "qp"), (1, "omega"))),
    Spec(
        "Hyperbolic2x2",
        nr.Hyperbolic2x2,
        (1.0, 2.0, 0.5, 0.3, 0.7, 0.4),
        params=((0, "pos"), (1, "pos"), (2, "real"), (3, "real"), (4, "real"), (5, "real")),
    ),
    Spec(
        "TransportSystem",
        TransportSystem,
        (1.0, 2.0, 0.5, 0.8),
        params=((0, "pos"), (1, "pos"), (2, "real"), (3, "real")),
    ),
    Spec("ReflectionController", ReflectionController, (0.2,), params=((0, "real"),)),
    Spec("FilteredController", nr.FilteredController, (0.5, 1.0), params=((0, "real"), (1, "pos"))),
    Spec("classify", nr.classify, (T0,), params=((0, "system"),)),
    Spec("characteristic", nr.characteristic, (T0, C0, 0.1), params=((0, "system"), (1, "controller"), (2, "nonneg"))),
    Spec("loop_factors", nr.loop_factors, (T0, C0), params=((0, "system"), (1, "controller"))),
    Spec(
        "k_region",
        nr.k_region,
        (T0, 0.1),
        {"Ks": [-0.5, 0.0, 0.5], "tol": 1e-3},
        ((0, "system"), (1, "pos"), ("Ks", "grid_or_none"), ("tol", "pos_or_none")),
    ),
    Spec(
        "stability_chart",
        nr.stability_chart,
        (T0, [0.1, 0.2], [0.1, 0.2]),
        {"quantity": "count"},
        ((0, "system"), (1, "grid"), (2, "grid"), ("quantity", "choice")),
    ),
    Spec("tradeoff", nr.tradeoff, (T0, [0.1, 0.2]), params=((0, "system"), (1, "grid"))),
    Spec(
        "ab_region", nr.ab_region, (T0, 0.1, [0.1], [0.2]), params=((0, "system"), (1, "pos"), (2, "grid"), (3, "grid"))
    ),
    Spec(
        "simulate",
        nr.simulate,
        (T0, C0, 0.1, 1.0, _sin, _sin, 20),
        params=(
            (0, "system"),
            (1, "controller"),
            (2, "nonneg"),
            (3, "pos"),
            (4, "state"),
            (5, "state"),
            (6, "int_or_none"),
        ),
    ),
    Spec("rouche_delay_bound", nr.rouche_delay_bound, (T0, C0), params=((0, "system"), (1, "controller"))),
    Spec(
        "QuasiTransferFunction",
        nr.QuasiTransferFunction,
        (A0, B0),
        params=((0, "qp_or_number"), (1, "qp_or_number")),
        extra_bad={1: [0.0, QuasiPolynomial([[0.0]], [0.0])]},
    ),
    Spec(
        "closed_loop_tf",
        nr.closed_loop_tf,
        (T0, C0, 0.1),
        {"output": "v"},
        ((0, "system"), (1, "controller"), (2, "nonneg"), ("output", "choice")),
    ),
    Spec("open_loop_tf", nr.open_loop_tf, (T0,), params=((0, "system"),)),
    Spec("boundary_function", nr.boundary_function, (T0, [1j, 2.0 + 1j]), params=((0, "system"), (1, "omega"))),
    Spec("to_frd", nr.to_frd, (F0, [0.1, 1.0]), params=((0, "qp"), (1, "omega"))),
    Spec(
        "certify",
        nr.certify,
        (T0, C0, 0.1),
        {"k_region": False},
        ((0, "system"), (1, "controller"), (2, "pos"), ("region", "region_or_none")),
    ),
    Spec(
        "nyquist_response",
        nr.plots.nyquist_response,
        (A0, B0, 0.5, 50.0, 201),
        params=((0, "qp_or_number"), (1, "qp_or_number"), (2, "nonneg"), (3, "pos"), (4, "int")),
    ),
]


def has_nan(obj: Any, depth: int = 0) -> bool:
    """A NaN anywhere in a result (numbers, arrays, sequences, dicts, dataclass fields)."""
    if depth > 6:
        return False
    if isinstance(obj, (float, complex, np.floating, np.complexfloating)):
        return bool(np.isnan(obj))
    if isinstance(obj, np.ndarray):
        return obj.dtype.kind in "fc" and bool(np.isnan(obj).any())
    if isinstance(obj, (list, tuple)):
        return any(has_nan(v, depth + 1) for v in obj)
    if isinstance(obj, dict):
        return any(has_nan(v, depth + 1) for v in obj.values())
    if is_dataclass(obj) and not isinstance(obj, type):
        return any(has_nan(getattr(obj, f.name, None), depth + 1) for f in fields(obj))
    return False


@st.composite
def bad_calls(draw: st.DrawFn) -> tuple[Spec, int | str, Any, bool]:
    spec = draw(st.sampled_from(SPECS))
    p, tag = draw(st.sampled_from(spec.params))
    bad, maybe = VALUES[tag]
    bad = bad + spec.extra_bad.get(p, [])
    pool = [(v, True) for v in bad] + [(v, False) for v in maybe]
    value, invalid = draw(st.sampled_from(pool))
    return spec, p, value, invalid


@budget(ci=90, weight=4.0)
@given(bad_calls())
def _prop_bad_input(bc: tuple) -> None:
    test = "bad_input"
    spec, p, value, invalid = bc
    STATS.case()
    args, kwargs = list(spec.args), dict(spec.kwargs)
    if isinstance(p, int):
        args[p] = value
    else:
        kwargs[p] = value
    name = spec.param_name(p)
    case = f"{spec.name}: {name} = {value!r} ({'invalid' if invalid else 'extreme'})"
    with memory_cap(MEMORY_HEADROOM):
        out = call(spec.fn, *args, seconds=min(EXAMPLE_SECONDS, 30.0), **kwargs)
    if out.kind == "refused":
        STATS.refusal(test)
        return
    if out.kind in ("wrong", "hang"):
        STATS.contradiction(test, out.describe(), case)
        return
    if out.kind == "rejected":
        msg = f"{getattr(out.error, 'name', '')} {out.error}"
        STATS.claim(name in msg, test, f"error names another parameter: {out.describe()}", case)
        return
    if invalid:
        STATS.contradiction(test, "silently accepted: returned without error", case)
        return
    STATS.claim(not has_nan(out.value), test, "NaN in the result", case)


def test_bad_input() -> None:
    """Every public function fed bad input: a named ParameterError (or a refusal), nothing else."""
    run(_prop_bad_input, "bad_input")


def test_the_pde_oracle_confirms_a_root_before_it_contradicts() -> None:
    """A case ``make fuzz`` drew: rho q = -4.6e-150, so F(.; 0) = 1 - (rho - K) q e^{-tau s} has its only
    chain at Re s = ln|(rho - K) q| / tau = -145.84 (the proven bracket's end). The oracle's secant
    iteration stalled left of it at points where F = 1 (the difference of terms of size e^{340}): they
    are no zeros, and the harness now asks the oracle to confirm a root before it calls it a contradiction."""
    o = PDELoop(
        2.9280591919165277,
        0.49597765052394926,
        3.9664943207385134e-275,
        1.2756253130979234,
        -0.5,
        9.178346331341683e-150,
        ("reflection", 2.2250738585072014e-308),
    )
    for stalled in (-143.41334419802462 + 108.24002246441951j, -144.3601572513879 + 37.463871649579744j):
        assert abs(complex(o.F_mp(stalled, 0.0))) > 0.9 and not o.is_zero(stalled, 0.0)
    paper = PDELoop(1.0, 1.0, 1.0, 1.0, 1.0, 0.85, ("reflection", 0.1))
    root = complex(paper.polish(complex(-0.1438, 3.14), 0.0))  # ln(0.75)/2 + i pi (eq. (56)-(58))
    assert abs(root - complex(np.log(0.75) / 2, np.pi)) < 1e-12 and paper.is_zero(root, 0.0)


def test_the_nplusm_oracle_on_known_cases() -> None:
    """The ``n + m`` oracle against closed forms and against the ODE oracle of the ``1 + 1`` plant.

    Without couplings ``Phi`` is diagonal and ``F = 1 - sum_i (R_i + K_i e^{-delta s}) Q_i e^{-(1/lam_i + 1/mu) s}``;
    with one term (``a = R Q``, ``b = K Q``) a crossing has ``|1 - a e^{-i w tau}| = |b|``, i.e.
    ``cos(w tau) = (1 + a^2 - b^2) / (2 a)``, and ``e^{-i w delta} = -(1 - a e^{-i w tau}) / (-b e^{-i w tau})``.
    With diagonal ``Q, R, K`` and two actuators the determinant is the product of two such loops.
    """
    s, d = mp.mpc("0.3", "2.7"), 0.7
    o = NPlusMLoop([1.0, 2.5], [1.25], np.zeros((3, 3)), [[0.5], [0.375]], [[0.25, -0.125]], [[0.5, 0.25]])
    with mp.workdps(40):
        closed = 1 - mp.fsum(
            (mp.mpf(r) + mp.mpf(k) * mp.exp(-d * s)) * mp.mpf(q) * mp.exp(-(1 / mp.mpf(lam) + mp.mpf("0.8")) * s)
            for r, k, q, lam in ((0.25, 0.5, 0.5, 1.0), (-0.125, 0.25, 0.375, 2.5))
        )
        assert abs(o.F_mp(s, d) - closed) < mp.mpf(10) ** -28
    # the 1 + 1 plant with U = k u(t, 1) against the Taylor integration of its ODE (20 digits)
    lam, mu, a, b, c, dd, q, rho, k = 1.2, 0.8, 0.3, 1.1, -0.7, -0.25, 0.6, 0.4, 0.35
    ode = VaryingPDELoop(
        lam, mu, 1.0, {n: Profile("sin", v) for n, v in zip("abcd", (a, b, c, dd))}, q, rho, ("state", k)
    )
    A, B, _ = ode.factors_mp(s)
    M0, M1 = NPlusMLoop([lam], [mu], [[a, b], [c, dd]], [[q]], [[rho]], [[k]]).matrices_mp(s, 40)
    with mp.workdps(30):  # the ODE oracle works at 20 digits and also divides by e^{D(L)}
        scale = mp.exp(-ode.D_L)
        assert abs(M0[0, 0] * scale - A) < 1e-18 and abs(M1[0, 0] * scale - B) < 1e-18
    # crossings of one loop and of two decoupled loops (m = 2)
    loops = [(1.0, 1.0, 1.0, 0.5, 0.625), (2.0, 0.5, 1.0, -0.75, 0.5)]  # (lam, mu, q, rho, k): a = rho q, b = k q
    truth: list[list[tuple[float, float]]] = []
    for lam, mu, q, rho, k in loops:
        tau, a, b = 1 / lam + 1 / mu, rho * q, k * q
        theta = math.acos((1 + a * a - b * b) / (2 * a))
        found = []
        for wt in sorted(x + 2 * math.pi * j for j in range(4) for x in (theta, 2 * math.pi - theta)):
            w = wt / tau
            e = complex(math.cos(wt), -math.sin(wt))
            found.append((w, float(np.angle(-(1 - a * e) / (-b * e)) * -1 % (2 * math.pi) / w)))
        truth.append([c for c in found if c[0] <= 10.0])
    one = NPlusMLoop([1.0], [1.0], np.zeros((2, 2)), [[1.0]], [[0.5]], [[0.625]])
    got = one.crossings_in_band(10.0)
    assert len(got) == len(truth[0]) and np.allclose(got, truth[0], rtol=1e-12, atol=0)
    w0, d0 = truth[0][0]
    wc, dc = one.crossing_near(w0 * (1 + 1e-9), d0 * (1 + 1e-9))
    assert abs(wc - w0) < 1e-13 and abs(dc - d0) < 1e-12
    two = NPlusMLoop(
        [1.0, 2.0], [1.0, 0.5], np.zeros((4, 4)), np.diag([1.0, 1.0]), np.diag([0.5, -0.75]), np.diag([0.625, 0.5])
    )
    got = sorted(two.crossings_in_band(10.0))
    both = sorted(truth[0] + truth[1])
    assert len(got) == len(both) and np.allclose(got, both, rtol=1e-12, atol=0)
