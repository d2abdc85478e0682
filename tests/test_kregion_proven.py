"""The ends of the admissible gains of ``U_BS2(K)`` proven for the PDE: ``k_region(..., rigorous=True)``.

The oracle shares no code with nrobust's loops: the Laplace-domain solution of the paper's plant
(``lam = mu = sigma_pm = sigma_mp = q = 1``, ``rho = 0.85``) in closed form, ``[u; v]' = M [u; v]``
with ``M^2 = (s^2 - 1) I`` so that ``exp(M) = cosh(k) I + sinh(k)/k M``, ``k^2 = s^2 - 1``, and the
equations of an end (a crossing at ``delta_max``, or the double zero of ``|A|^2 - |B|^2`` of a pair
birth) solved by ``mpmath.findroot`` at 40 digits. Its error (``1e-35`` or less) is negligible
beside the proven brackets (``1e-13`` and wider), so each bracket must hold the oracle's end exactly.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from _oracles import paper_factors

from nrobust import (
    CertificationError,
    GeneralHyperbolic2x2,
    Hyperbolic2x2,
    ReflectionController,
    StateFeedback,
    certify,
    k_region,
)
from nrobust.hyperbolic.analyses import kregion
from nrobust.margins.gain import GainEnd
from nrobust.reports.certificate import CHECKED, PROVEN
from nrobust.reports.report import write_report

pytest.importorskip("flint")

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)


def _crossing_end(K0: str, w0: str, delta_max: float) -> mp.mpf:
    """The gain with a root at ``i w`` for ``delta = delta_max``: ``A + B e^{-i w delta_max} = 0``."""
    with mp.workdps(40):
        d = mp.mpf(delta_max)

        def F(K: mp.mpf, w: mp.mpf) -> list[mp.mpf]:
            A, B = paper_factors(mp.mpc(0, w), K)
            value = A + B * mp.exp(-mp.mpc(0, w) * d)
            return [value.real, value.imag]

        K, _ = mp.findroot(F, (mp.mpf(K0), mp.mpf(w0)))
        return +K


def _pair_birth(K0: str, w0: str) -> tuple[mp.mpf, mp.mpf, mp.mpf]:
    """``(K, w, delay)`` where ``g(w; K) = |A(i w)|^2 - |B(i w; K)|^2`` has a double zero in ``w``."""
    with mp.workdps(40):

        def g(w: mp.mpf, K: mp.mpf) -> mp.mpf:
            A, B = paper_factors(mp.mpc(0, w), K)
            return abs(A) ** 2 - abs(B) ** 2

        K, w = mp.findroot(lambda K, w: [g(w, K), mp.diff(lambda x: g(x, K), w)], (mp.mpf(K0), mp.mpf(w0)))
        A, B = paper_factors(mp.mpc(0, w), K)
        theta = mp.arg(-B / A)
        return +K, +w, (theta if theta >= 0 else theta + 2 * mp.pi) / w


def _holds(end, K_true: mp.mpf) -> bool:
    return bool(abs(mp.mpf(end.K) - K_true) <= end.accuracy)


def test_paper_ends_are_proven_and_hold_the_mpmath_ends() -> None:
    """``delta_max = 0.1``: two crossing ends (w = 3.1382 and 28.2652), each proven within ``tol`` (1.5e-11)."""
    region = k_region(PAPER, 0.1, rigorous=True)
    ((lo, hi),) = region.ends
    assert region.proven == ((True, True),) and region.unproven == () and region.ends_proven
    assert (lo.kind, hi.kind) == ("crossing", "crossing")
    assert lo.accuracy <= 1.0001 * region.tol and hi.accuracy <= 1.0001 * region.tol
    assert _holds(lo, _crossing_end("-0.0644694183", "3.1382211", 0.1))
    assert _holds(hi, _crossing_end("0.146404806", "28.265153", 0.1))
    assert repr(region).endswith("ends proven for the PDE)")
    assert "0.14640480614 +- 2e-11" in repr(region)


def test_a_pair_birth_end_is_proven_and_holds_the_mpmath_tangency() -> None:
    """``delta_max = 0.2``: the upper end is the birth of a pair of crossings (w = 12.5416, delay 0.19689)."""
    region = k_region(PAPER, 0.2, rigorous=True)
    ((lo, hi),) = region.ends
    assert region.proven == ((True, True),) and (lo.kind, hi.kind) == ("crossing", "pair_birth")
    K_b, w_b, delay_b = _pair_birth("0.1307588", "12.5416")
    assert delay_b < 0.2 and abs(w_b - hi.omega) < 1e-3
    assert _holds(hi, K_b)
    assert _holds(lo, _crossing_end("0.0348760111", "3.1553484", 0.2))


def test_a_bracket_too_tight_for_floating_point_is_proven() -> None:
    """At ``tol = 1e-13`` the floating-point count outside the lower end fails (its root is 5e-14 from the axis);
    the proven margins decide both ends, and the brackets hold the oracle's ends."""
    with pytest.raises(CertificationError, match="could not be verified"):
        k_region(PAPER, 0.1, Ks=[0.0], tol=1e-13)
    region = k_region(PAPER, 0.1, Ks=[0.0], tol=1e-13, rigorous=True)
    ((lo, hi),) = region.ends
    assert region.ends_proven and max(lo.accuracy, hi.accuracy) < 1.1e-13
    assert _holds(lo, _crossing_end("-0.0644694183", "3.1382211", 0.1))
    assert _holds(hi, _crossing_end("0.146404806", "28.265153", 0.1))


def test_an_end_the_proofs_cannot_decide_is_never_proven() -> None:
    """At ``tol = 1e-14`` the margin's ball (3.4e-14 wide) straddles ``delta_max`` inside the end: no proof, and
    as floating point fails too, ``k_region`` refuses, saying both."""
    K = float(_crossing_end("-0.0644694183", "3.1382211", 0.1))
    why = kregion._prove_end(PAPER, GainEnd(K, "crossing", 3.1382, 0.1), K + 1e-14, K - 1e-14, 0.1)
    assert why is not None and "does not exceed 0.1" in why
    with pytest.raises(CertificationError, match="nor proven"):
        k_region(PAPER, 0.1, Ks=[0.0], tol=1e-14, rigorous=True)


def test_ends_of_a_normal_form_stay_checked_with_the_reason() -> None:
    """The paper's plant given as a general plant: its loops are those of the normal form computed in floating
    point, so the ends are checked, not proven, and the region says why."""
    general = GeneralHyperbolic2x2(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.85)
    region = k_region(general, 0.1, rigorous=True)
    assert region.proven == ((False, False),) and not region.ends_proven
    assert len(region.unproven) == 2 and all("normal form" in why for why in region.unproven)
    assert "ends not all proven" in repr(region)


def test_ends_of_a_bisected_family_stay_checked_with_the_reason() -> None:
    """``U = k u(t, 1)`` on a weakly coupled plant: one interval of gains, bisected, its ends not proven."""
    weak = Hyperbolic2x2(1.0, 1.0, 0.1, 0.1, 1.0, 0.85)
    region = k_region(weak, 0.1, controller=StateFeedback, Ks=[-0.1, 0.0, 0.1], tol=1e-2, rigorous=True)
    assert region.method == "bisection" and len(region.ends) == 1 and not region.ends_proven
    assert all(pair == (False, False) for pair in region.proven) and "bisected" in region.unproven[0]


def test_the_floating_point_path_is_unchanged() -> None:
    region = k_region(PAPER, 0.1)
    assert not region.rigorous and region.proven == () and region.unproven == () and not region.ends_proven
    assert "proven" not in repr(region) and region.ends[0][0].accuracy == region.tol


def test_rigorous_must_be_a_bool() -> None:
    with pytest.raises(ValueError, match="rigorous"):
        k_region(PAPER, 0.1, rigorous="yes")  # type: ignore[arg-type]


def test_certificate_says_the_ends_are_proven(tmp_path) -> None:
    cert = certify(PAPER, ReflectionController(0.1), delta_max=0.1, rigorous=True)
    claims = {c.name: c for c in cert.claims}
    ends = claims["admissible gain ends"]
    assert ends.status == PROVEN and claims["admissible gains"].status == CHECKED
    assert "-0.06446941833 +- 2e-11 (crossing), 0.14640480614 +- 2e-11 (crossing)" in ends.statement
    assert "floating-point scan" in ends.statement  # the interior is not claimed proven
    text = write_report(cert, tmp_path / "report").markdown.read_text()
    assert "each end proven for the PDE" in text
    plain = certify(PAPER, ReflectionController(0.1), delta_max=0.1)
    assert "admissible gain ends" not in {c.name for c in plain.claims}


def test_ends_of_a_model_stay_checked_in_the_certificate() -> None:
    """A coupling given as samples: the loops are the kernel route's model, whose proven margins are the model's,
    so the certificate's claim on the ends is checked, saying so."""
    x = np.linspace(0.0, 1.0, 11)
    sampled = GeneralHyperbolic2x2(1.0, 1.0, 0.0, (x, np.ones(11)), 1.0, 0.0, 1.0, 0.85)
    cert = certify(sampled, ReflectionController(0.1), delta_max=0.1, rigorous=True)
    (ends,) = [c for c in cert.claims if c.name == "admissible gain ends"]
    assert ends.status == CHECKED and "proven for a model of the plant only" in ends.statement
    assert cert.k_region is not None and not cert.k_region.ends_proven


def test_an_end_at_the_strong_stability_limit_says_how_it_is_proven() -> None:
    """On the uncoupled ``Hyperbolic2x2(1, 1, 0, 0, 0.7, 0.9)`` the ends are the strong-stability limits
    ``+-(1 - |rho q|) / |q|`` (closed form): the outer probe is proven not admissible by its difference operator,
    proven not strongly stable, which the proven claim names (it gave only a crossing or the nominal loop)."""
    plant = Hyperbolic2x2(1.0, 1.0, 0.0, 0.0, 0.7, 0.9)
    cert = certify(plant, ReflectionController(0.1), delta_max=0.2, rigorous=True)
    ends = {c.name: c for c in cert.claims}["admissible gain ends"]
    assert ends.status == PROVEN and "a difference operator proven not strongly stable" in ends.statement
    kreg = k_region(plant, 0.2, rigorous=True)
    limit = (1.0 - 0.9 * 0.7) / 0.7
    (lo, hi), *_ = kreg.ends
    assert abs(lo.K + limit) <= lo.accuracy and abs(hi.K - limit) <= hi.accuracy
