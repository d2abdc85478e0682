"""The PDE's loop of the collocated observer under U_BS2(K) on a coupled plant with constant couplings, at 40 digits.

Nothing here imports nrobust. The oracle:

* the backstepping kernels (24)-(29) of a plant with constant couplings are entire in ``(x, xi)``: each pair
  (a kernel ``A`` transported along ``(1, 1)``, ``A_x + A_xi = a B``, and ``B`` along ``(1, -kappa)``,
  ``B_x - kappa B_xi = b A``, with ``B(x, x) = g`` and ``A(x, 0) = r B(x, 0)``) has Taylor coefficients
  ``A_ij, B_ij`` of ``x^i xi^j`` found degree by degree: ``(i + 1) B_{i+1, j} = kappa (j + 1) B_{i, j+1} +
  b A_ij`` makes the coefficients of degree ``n + 1`` affine in ``B_{0, n+1}``, fixed by ``sum B = 0``
  (the diagonal), and ``(i + 1) A_{i+1, j} = a B_ij - (j + 1) A_{i, j+1}`` those of ``A`` affine in
  ``A_{0, n+1}``, fixed by the reflection at ``xi = 0``. Degree 50: the last degree's coefficients are below
  1e-55 on these plants;
* the law U_BS2(K), eq. (53): ``k = -K``, ``g_u = K^{vu}(1, .) - (rho - K) K^{uu}(1, .)``,
  ``g_v = K^{vv}(1, .) - (rho - K) K^{uv}(1, .)``; the observer's gains ``p_u = -lam K'^{vv}(1, .)``,
  ``p_v = -lam K'^{vu}(1, .)`` from the dual plant ``(mu, lam, sigma_pm, sigma_mp, lam q / mu, 0)``: both
  checked in ``test_collocated_integral_law_oracle.py`` by what they must do (the state feedback's target
  ``1 - (rho - K) q e^{-tau s}`` and a nilpotent error, ``e^{-s/mu} Delta(s) = 1``), not by the package's
  reading of them;
* in the Laplace domain ``[u; v]' = M(s) [u; v] + f``: the plant's profile ``Y`` from ``Y(0) = [q; 1]`` and the
  error's particular part ``Z`` (``f = [-p_u / lam; p_v / mu]`` per unit ``u~(1)``, ``Z(0) = 0``) as Taylor
  series in ``x`` (entire; truncated as :data:`X_TERMS` says); the error driven by
  ``v~(1) = kappa u~(1) + W``, ``W = 1``, is ``Y v_0 + Z u_1`` with ``u_1 = Y_u(1) v_0 + Z_u(1) u_1`` and
  ``1 + kappa u_1 = Y_v(1) v_0 + Z_v(1) u_1``;
  ``C_u = k u_1 + int g . (Y v_0 + Z u_1)``, the plant's ``T = (k Y_u(1) + int g . Y) / (Y_v(1) - rho Y_u(1))``,
  and the loop ``U_c (1 - C_u + (C_u - T) e^{-delta s}) = 0``; times ``1 - Phi = e^{-s/mu} (Y_v(1) - rho
  Y_u(1))`` and the error's function ``E = e^{-s/mu} Delta``, the package's ``(A_o, B_o)``;
* crossings ``|1 - C_u(i w)| = |C_u(i w) - T(i w)|`` by ``mpmath.findroot``, then
  ``e^{-i w delta} = -(1 - C_u) / (C_u - T)``.
"""

from __future__ import annotations

import mpmath as mp

DPS = 40
#: Degree of the kernels' Taylor polynomials in ``(x, xi)``.
DEGREE = 50
#: Most terms of the Taylor series in ``x`` of the Laplace-domain profiles: a series stops past the gains' degree
#: and ``2 |M(s)|`` (``|M|`` the largest row sum) once its last term is below ``10^-(DPS + 5)``; the terms then
#: fall by at least half each (``|M| / (n + 1)``), so the rest is at most the last term.
X_TERMS = 1200


def kernel_pair(a, b, kappa, g, r):
    """Taylor coefficients ``{(i, j): c}`` of the pair ``(A, B)`` (module docstring) up to :data:`DEGREE`."""
    A, B = {(0, 0): r * g}, {(0, 0): g}
    for n in range(DEGREE):
        m = n + 1
        free = [mp.mpf(0)] * (m + 1)  # B_{i, m-i} = free_i + slope_i B_{0, m}
        slope = [mp.mpf(1)] + [mp.mpf(0)] * m
        for i in range(m):
            free[i + 1] = (kappa * (m - i) * free[i] + b * A[(i, n - i)]) / (i + 1)
            slope[i + 1] = kappa * (m - i) * slope[i] / (i + 1)
        top = -mp.fsum(free) / mp.fsum(slope)
        for i in range(m + 1):
            B[(i, m - i)] = free[i] + slope[i] * top
        free = [mp.mpf(0)] * (m + 1)  # A_{i, m-i} = free_i + slope_i A_{0, m}
        slope = [mp.mpf(1)] + [mp.mpf(0)] * m
        for i in range(m):
            free[i + 1] = (a * B[(i, n - i)] - (m - i) * free[i]) / (i + 1)
            slope[i + 1] = -(m - i) * slope[i] / (i + 1)
        top = (r * B[(m, 0)] - free[m]) / slope[m]
        for i in range(m + 1):
            A[(i, m - i)] = free[i] + slope[i] * top
    return A, B


def traces(lam, mu, spm, smp, q):
    """``K^{uu}, K^{uv}, K^{vu}, K^{vv}`` at ``x = 1`` as coefficients in ``xi``, and the last degree's largest."""
    vv, vu = kernel_pair(spm / mu, smp / mu, lam / mu, -smp / (lam + mu), lam * q / mu)
    uu, uv = kernel_pair(-smp / lam, -spm / lam, mu / lam, spm / (lam + mu), mu / (lam * q))
    out = []
    for C in (uu, uv, vu, vv):
        coefficients = [mp.mpf(0)] * (DEGREE + 1)
        for (_, j), c in C.items():
            coefficients[j] += c
        out.append(coefficients)
    last = max(abs(c) for C in (uu, uv, vu, vv) for (i, j), c in C.items() if i + j == DEGREE)
    return out, last


def horner(coefficients, x):
    """The polynomial of increasing ``coefficients`` at ``x`` (Horner)."""
    out = mp.mpf(0)
    for c in reversed(coefficients):
        out = out * x + c
    return out


class CollocatedPDE:
    """The PDE's collocated loop under U_BS2(K) (module docstring)."""

    def __init__(self, args, K, kappa=0.0):
        with mp.workdps(DPS + 10):
            self.lam, self.mu, self.spm, self.smp, self.q, self.rho = (mp.mpf(v) for v in args)
            self.K, self.kappa = mp.mpf(K), mp.mpf(kappa)
            (kuu, kuv, kvu, kvv), last = traces(self.lam, self.mu, self.spm, self.smp, self.q)
            reflected = self.rho - self.K
            self.g_u = [a - reflected * b for a, b in zip(kvu, kuu, strict=True)]
            self.g_v = [a - reflected * b for a, b in zip(kvv, kuv, strict=True)]
            dual = (self.mu, self.lam, self.spm, self.smp, self.lam * self.q / self.mu)
            (_, _, dvu, dvv), dual_last = traces(*dual)
            self.p_u = [-self.lam * c for c in dvv]
            self.p_v = [-self.lam * c for c in dvu]
            self.last = max(last, dual_last)
        self._moments: list[tuple] = []

    def _profiles(self, s):
        """Taylor coefficients in ``x`` of ``Y`` and ``Z`` (module docstring)."""
        m11, m12, m21, m22 = -s / self.lam, self.spm / self.lam, -self.smp / self.mu, s / self.mu
        Y, Z = [(self.q, mp.mpf(1))], [(mp.mpf(0), mp.mpf(0))]
        size = max(abs(m11) + abs(m12), abs(m21) + abs(m22))
        for n in range(X_TERMS):
            last = max(abs(c) for c in (*Y[-1], *Z[-1]))
            if n > max(DEGREE, 2 * size) and last < mp.mpf(10) ** -(DPS + 5):
                break
            (yu, yv), (zu, zv) = Y[-1], Z[-1]
            fu = -self.p_u[n] / self.lam if n <= DEGREE else 0
            fv = self.p_v[n] / self.mu if n <= DEGREE else 0
            Y.append(((m11 * yu + m12 * yv) / (n + 1), (m21 * yu + m22 * yv) / (n + 1)))
            Z.append(((m11 * zu + m12 * zv + fu) / (n + 1), (m21 * zu + m22 * zv + fv) / (n + 1)))
        else:
            raise AssertionError(f"the profiles' series at s = {s} did not reach 1e-{DPS + 5} in {X_TERMS} terms")
        return Y, Z

    def _law(self, series):
        """``int_0^1 g_u S_u + g_v S_v dx`` of a Taylor series ``S`` (``int_0^1 g x^n dx`` cached by ``n``)."""
        while len(self._moments) < len(series):
            n = len(self._moments)
            self._moments.append(tuple(mp.fsum(c / (n + j + 1) for j, c in enumerate(g)) for g in (self.g_u, self.g_v)))
        return mp.fsum(a * su + b * sv for (su, sv), (a, b) in zip(series, self._moments, strict=False))

    def responses(self, s):
        """``(C_u, T, e^{-s/mu} Delta, 1 - Phi, e^{-s/mu} (Y_v(1) - (rho - K) Y_u(1) - int g . Y))``."""
        # the series' terms grow to about e^{|M|} before they fall: that many more digits keep DPS + 10 in the sum
        size = abs(complex(s)) / float(min(self.lam, self.mu)) + float(
            abs(self.spm) / self.lam + abs(self.smp) / self.mu
        )
        with mp.workdps(DPS + 10 + int(size / 2.302585) + 1):
            s = mp.mpc(s)
            Y, Z = self._profiles(s)
            yu, yv = (mp.fsum(y[c] for y in Y) for c in (0, 1))
            zu, zv = (mp.fsum(z[c] for z in Z) for c in (0, 1))
            law_y, law_z = self._law(Y), self._law(Z)
            delta = yu * (zv - self.kappa) - yv * (zu - 1)
            v0, u1 = -(zu - 1) / delta, yu / delta
            k = -self.K
            response = k * u1 + law_y * v0 + law_z * u1
            plant = (k * yu + law_y) / (yv - self.rho * yu)
            scale = mp.exp(-s / self.mu)
            target = scale * (yv - (self.rho + k) * yu - law_y)
            return response, plant, scale * delta, scale * (yv - self.rho * yu), target

    def factors(self, s):
        """The package's ``(A_o, B_o)``: ``(1 - Phi) E (1 - C_u, C_u - T)``."""
        response, plant, error, open_loop, _ = self.responses(s)
        return open_loop * error * (1 - response), open_loop * error * (response - plant)

    def crossing(self, omega):
        """``(w, delta)`` of the crossing near ``omega``."""
        with mp.workdps(DPS):

            def gap(w):
                response, plant, *_ = self.responses(1j * w)
                return abs(1 - response) - abs(response - plant)

            w = mp.findroot(gap, mp.mpf(omega))
            response, plant, *_ = self.responses(1j * w)
            return w, (-mp.arg(-(1 - response) / (response - plant)) % (2 * mp.pi)) / w
