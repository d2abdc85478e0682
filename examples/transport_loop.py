"""The transport closed loop of the paper's section 2, end to end
==============================================================

Two transport equations with lam = mu = q = 1 and proximal reflection rho = 0.85
(open-loop gain rho q = 0.85, between 1/2 and 1) under the reflection-preserving
control U = -K u(1) with K = 0.1 and a loop delay delta = 0.1. The characteristic
function (eq. (13)) is

    F(s) = 1 - 0.85 e^{-2 s} + 0.1 e^{-2.1 s}.

The script prints the paper's classification, the strong stability of the difference
operator (Hale and Verduyn Lunel), the certified roots in [-3, 1] x [-0.5, 200], and the
same analysis for the finite-time law U = -rho u(1), whose delayed loop is not strongly
stable (eq. (11)).

Run: ``python examples/transport_loop.py``
"""

from __future__ import annotations

import nrobust
from nrobust.hyperbolic.plants.hyperbolic2x2 import TransportSystem

REGION = (-3.0, 1.0, -0.5, 200.0)


def analyse(system: TransportSystem, controller: nrobust.hyperbolic.loops.controllers.Controller, delta: float) -> None:
    """Print the difference operator's verdict and the certified roots of one loop."""
    F = nrobust.characteristic(system, controller, delta)
    D = F.principal_part()
    print(f"\n{type(controller).__name__} {controller.to_dict()}, delta = {delta}")
    print(f"  characteristic function: {F}")
    print(
        f"  difference operator: gamma_0 = {D.gamma_0:.4f}, strongly stable: {D.is_strongly_stable()}, "
        f"strong spectral bound C_D = {D.strong_spectral_bound():.6f}"
    )
    roots = nrobust.find_roots(F, REGION)
    print(f"  certified count in {REGION}: {roots.count} (certified: {roots.certified})")
    rightmost = max(roots.roots, key=lambda z: z.real)
    print(f"  rightmost root: {rightmost:.10f}")
    print("  first roots by imaginary part:")
    for z in sorted(roots.roots, key=lambda z: z.imag)[:6]:
        print(f"    {z.real:+.12f} {z.imag:+.12f}j   |F| = {abs(F(z)):.1e}")


def main() -> None:
    system = TransportSystem(lam=1.0, mu=1.0, q=1.0, rho=0.85)
    print(system)
    print(nrobust.classify(system).statement)
    analyse(system, nrobust.ReflectionController(K=0.1), delta=0.1)
    analyse(system, nrobust.FiniteTimeController(), delta=0.1)


if __name__ == "__main__":
    main()
