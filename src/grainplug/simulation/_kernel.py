"""The time step of :mod:`.scheme`, compiled with numba: the same operations, cell by cell.

:class:`~grainplug.simulation.scheme.Integrator` is the readable NumPy reference;
this module repeats its step in loops that numba compiles (6.5 times faster on
2048 cells), and ``tests/test_simulation.py`` checks that both give the same step on
random states. Constants come in one float array (see :func:`pack`).

Two things make the loop over the faces, the hot spot, vectorize (four faces at a time,
half the time of a flux evaluation): the ``numpy`` error model (a division by zero gives
``inf`` or ``nan`` instead of a branch that raises; the largest speed is NaN as soon as one
cell's is not finite, which stops the time loop, and :func:`~grainplug.simulation.simulate`
checks every saved state) and the constants read into scalars before the loop (a load from the
constants array inside it could alias the stores). Powers cannot vectorize (no vector
``pow`` without Intel's SVML), hence ``r`` reconstructed beside ``P`` and :func:`_pow`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .equations import C_FLOOR, Closure
from .scheme import SSP_STAGES

_G2 = 2.0 - math.sqrt(2.0)
_BETA = _G2 / 2.0
_A = 1.0 / (_G2 * (2.0 - _G2))
LAWS = {"v2": 0, "v|v|": 0, "coulomb-frozen": 1, "coulomb-weight": 2, "coulomb-janssen": 3}
BCS = {"periodic": 0, "open": 1, "outflow": 2}

# indices into the constants array
(K_C0, K_P0, K_GAMMA, K_KAPPA, K_COS, K_LAW, K_F0, K_ALPHA, K_K0, K_BAL, K_JAM, K_FR, K_CMIN, K_CMAX, K_BC,
 K_IN_C, K_IN_Q, K_IN_M, K_PEND, K_DX, K_STAGES, K_JTERM, K_WALL, K_VEPS, K_STOKES, K_DTMIN, K_COLUMN,
 K_SEAL, K_STICK) = range(29)


def pack(cl: Closure, bc_kind: str, inlet: np.ndarray, P_end: float, dx: float, dt_floor: float = 0.0,
         inlet_seal: float = 0.0) -> np.ndarray:
    """The constants of one integration as a float array (the scheme's constants too: a compiled
    function keeps the value of a module global it read, even from its on-disk cache)."""
    return np.array([cl.c0, cl.P0, cl.gamma, cl.kappa, cl.cos_theta, LAWS[cl.law], cl.F0, cl.alpha, cl.K0,
                     cl.balance_force, 1.0 if cl.jamming else 0.0, cl.jam_fr, cl.jam_c_min, cl.jam_c_max,
                     BCS[bc_kind], inlet[0], inlet[1], inlet[2], P_end, dx, SSP_STAGES, cl.jterm, cl.wall, cl.v_eps,
                     1.0 if cl.stokes else 0.0, dt_floor, 1.0 if cl.column else 0.0, inlet_seal, cl.stick],
                    dtype=np.float64)


@njit(cache=True, inline="always", error_model="numpy")
def _pj(c, jam, fr, cmin, cmax):
    """The jamming pressure and its slope (0 without jamming), as :meth:`Closure.jamming_pressure`; the
    constants as scalars, so that a loop calling it still vectorizes."""
    if not jam:
        return 0.0, 0.0
    x = max(c - cmin, 0.0)
    y = max(cmax - c, 1e-4)
    return fr * x * x / y**5, fr * (2 * x / y**5 + 5 * x * x / y**6)


@njit(cache=True, inline="always", error_model="numpy")
def _pow(x, e):
    """``max(x, 0) ** e`` as ``exp(e log x)``: a third faster than ``pow``, within a few ulp; NaN stays NaN
    (so that the time loop's check sees it)."""
    return 0.0 if x <= 0.0 else math.exp(e * math.log(x))


@njit(cache=True, inline="always", error_model="numpy")
def _mc(dl, dr):
    if dl * dr <= 0.0:
        return 0.0
    s = min(min(2 * abs(dl), 2 * abs(dr)), 0.5 * abs(dl + dr))
    return s if dl > 0 else -s


@njit(cache=True, error_model="numpy")
def _prim(U, k, W):
    """Primitive ``(c, v, P)`` of the padded conserved state, and the air density ``r``, into ``W``."""
    P0, gam = k[K_P0], k[K_GAMMA]
    for i in range(U.shape[1]):
        c = U[0, i]
        W[0, i] = c
        W[1, i] = U[1, i] / max(c, C_FLOOR) if c > C_FLOOR else 0.0
        r = max(U[2, i] / (1 - c), 0.0)
        W[2, i] = P0 * _pow(r, gam)
        W[3, i] = r


@njit(cache=True, error_model="numpy")
def _pad(U, k, out):
    n = U.shape[1]
    out[:, 2:n + 2] = U
    bc = int(k[K_BC])
    for j in range(3):
        if bc == 0:
            out[j, 0], out[j, 1] = U[j, n - 2], U[j, n - 1]
            out[j, n + 2], out[j, n + 3] = U[j, 0], U[j, 1]
        else:
            if bc == 2:
                out[j, 0] = out[j, 1] = U[j, 0]
            else:
                inlet = k[K_IN_C + j]
                out[j, 0] = out[j, 1] = inlet
            out[j, n + 2] = out[j, n + 3] = U[j, n - 1]


@njit(cache=True, inline="always", error_model="numpy")
def _state(c, v, P, r, kap, gam, jam, fr, cmin, cmax, jt):
    """Flux, conserved variables and the extreme speeds of one face state (the constants as scalars, so that
    the compiler keeps them in registers and vectorizes the loop over the faces)."""
    cs = max(c, C_FLOOR)
    pj, dpj = _pj(c, jam, fr, cmin, cmax)
    m = r * (1 - c)
    b = jt * (v / (kap * cs))
    a = gam * P / (cs * (1 - c)) + dpj
    root = math.sqrt(b * b + 4 * a)
    return (c * v, c * v * v + jt * (v * v / (2 * kap)) + P + pj, m * v, c, c * v, m,
            v + 0.5 * (b - root), v + 0.5 * (b + root))


@njit(cache=True, error_model="numpy")
def _rate(U, k, Upad, W, out, acc, w):
    """The flux divergence ``-(H[f+1] - H[f]) / dx`` of every cell into ``out``; ``w`` times the grain flux
    through the first and the last face added to ``acc[0]`` and ``acc[1]`` (not periodic)."""
    n = U.shape[1]
    _pad(U, k, Upad)
    _prim(Upad, k, W)
    dx = k[K_DX]
    kap, gam, jam, fr, cmin, cmax = k[K_KAPPA], k[K_GAMMA], k[K_JAM] != 0.0, k[K_FR], k[K_CMIN], k[K_CMAX]
    jt = k[K_JTERM]
    H = np.empty((3, n + 1))
    S = np.empty((4, n + 4))  # limited slopes of the padded cells 1 .. n + 2, each computed once
    for j in range(4):
        for i in range(1, n + 3):
            S[j, i] = _mc(W[j, i] - W[j, i - 1], W[j, i + 1] - W[j, i])
    for f in range(n + 1):
        i = f + 1  # the face between padded cells i and i + 1
        wl0 = min(max(W[0, i] + 0.5 * S[0, i], 0.0), 1.0 - 1e-9)
        wl1 = W[1, i] + 0.5 * S[1, i]
        wl2 = W[2, i] + 0.5 * S[2, i]
        wr0 = min(max(W[0, i + 1] - 0.5 * S[0, i + 1], 0.0), 1.0 - 1e-9)
        wr1 = W[1, i + 1] - 0.5 * S[1, i + 1]
        wr2 = W[2, i + 1] - 0.5 * S[2, i + 1]
        wl3 = W[3, i] + 0.5 * S[3, i]
        wr3 = W[3, i + 1] - 0.5 * S[3, i + 1]
        fl0, fl1, fl2, ul0, ul1, ul2, lol, hil = _state(wl0, wl1, wl2, wl3, kap, gam, jam, fr, cmin, cmax, jt)
        fr0, fr1, fr2, ur0, ur1, ur2, lor, hir = _state(wr0, wr1, wr2, wr3, kap, gam, jam, fr, cmin, cmax, jt)
        ap = max(max(hil, hir), 0.0)
        am = min(min(lol, lor), 0.0)
        span = ap - am
        if not span > 0:
            span = 1.0
        H[0, f] = (ap * fl0 - am * fr0 + ap * am * (ur0 - ul0)) / span
        H[1, f] = (ap * fl1 - am * fr1 + ap * am * (ur1 - ul1)) / span
        H[2, f] = (ap * fl2 - am * fr2 + ap * am * (ur2 - ul2)) / span
    if int(k[K_BC]) == 1:  # the feed, no faster than a denser top cell's grains (scheme.inlet_flux)
        if U[0, 0] < k[K_IN_C]:
            H[0, 0] = k[K_IN_Q]
        else:
            H[0, 0] = k[K_IN_C] * min(max(U[1, 0] / U[0, 0], 0.0), k[K_IN_Q] / k[K_IN_C])
    if int(k[K_BC]) != 0:
        acc[0] += w * H[0, 0]
        acc[1] += w * H[0, n]
    for j in range(3):
        for i in range(n):
            out[j, i] = -(H[j, i + 1] - H[j, i]) / dx


@njit(cache=True, error_model="numpy")
def _hyperbolic(U, dt, k, Upad, W, acc):
    """SSPRK(s,2), as :meth:`Integrator.hyperbolic` (the grain through the ends added to ``acc``)."""
    n = U.shape[1]
    s = int(k[K_STAGES])
    h = dt / (s - 1)
    R = np.empty((3, n))
    V = U.copy()
    for _ in range(s - 1):
        _rate(V, k, Upad, W, R, acc, dt / s)
        for j in range(3):
            for i in range(n):
                V[j, i] = V[j, i] + h * R[j, i]
        for i in range(n):
            V[0, i] = min(max(V[0, i], 0.0), 1.0 - 1e-9)
    _rate(V, k, Upad, W, R, acc, dt / s)
    out = np.empty_like(U)
    for j in range(3):
        for i in range(n):
            out[j, i] = U[j, i] / s + (s - 1) / s * (V[j, i] + h * R[j, i])
    for i in range(n):
        out[0, i] = min(max(out[0, i], 0.0), 1.0 - 1e-9)
    return out


@njit(cache=True, error_model="numpy")
def _solve_tanh(c, aF, R, ve):
    """The root of ``c u + aF tanh(u / ve) = R``, as :func:`grainplug.simulation.scheme._solve_tanh`."""
    lo, hi = (R - aF) / c, (R + aF) / c
    u = (R - math.copysign(aF, R)) / c if abs(R) > aF else R / (c + aF / ve)  # sliding, or stuck (linear)
    for _ in range(200):
        t = math.tanh(u / ve)
        g = c * u + aF * t - R
        if g == 0:
            return u
        if g > 0:
            hi = u
        else:
            lo = u
        un = u - g / (c + aF * (1 - t * t) / ve)
        if not (lo < un < hi):
            un = 0.5 * (lo + hi)
        if abs(un - u) <= 1e-15 * max(abs(un), ve):
            return un
        u = un
    return u


@njit(cache=True, error_model="numpy")
def _column_stress(U, k, push, cap):
    """Janssen's stress carried down each dense stretch, as :func:`grainplug.simulation.scheme.column_stress`: the
    push of its gradient and the walls' largest friction of every cell into ``push`` and ``cap``."""
    n = U.shape[1]
    wall, cmin, dx, cos = k[K_WALL], k[K_CMIN], k[K_DX], k[K_COS]
    periodic = int(k[K_BC]) == 0
    decay = math.exp(-wall * dx)
    gain = (1.0 - decay) / wall
    start = -1
    for i in range(n):
        push[i] = 0.0
        cap[i] = 0.0
        if start < 0 and not U[0, i] > cmin:
            start = i
    if start < 0:  # dense everywhere
        if not periodic:
            start = 0
        else:  # the periodic solution: sigma_0 = decay^n sigma_0 + sum_j decay^(n-1-j) gain w_j
            s = 0.0
            for i in range(n):
                s = decay * s + U[0, i] * cos * gain
            s = s / (1.0 - decay**n)
            for i in range(n):
                s_next = decay * s + U[0, i] * cos * gain
                push[i] = -(s_next - s) / dx
                cap[i] = U[0, i] * cos + push[i]
                s = s_next
            return
    if not periodic:
        start = 0
    s = 0.0
    for t in range(n):
        i = (start + t) % n
        if not U[0, i] > cmin:
            s = 0.0
            continue
        w = U[0, i] * cos
        s_next = decay * s + w * gain
        cap[i] = w - (s_next - s) / dx
        j = i + 1
        if j >= n:
            j = 0 if periodic else -1
        last = j < 0 or not U[0, j] > cmin or (periodic and t == n - 1)
        push[i] = s / dx if last else -(s_next - s) / dx
        s = s_next


@njit(cache=True, error_model="numpy")
def _sources(U, dt, k):
    law = int(k[K_LAW])
    jam, fr, cmin, cmax = k[K_JAM] != 0.0, k[K_FR], k[K_CMIN], k[K_CMAX]
    ve = k[K_VEPS]
    column = k[K_COLUMN] != 0.0 and law == 3 and not ve > 0
    n = U.shape[1]
    push = np.zeros(n if column else 0)  # no allocation on the other laws' path
    cap = np.zeros(n if column else 0)
    if column:
        _column_stress(U, k, push, cap)
    for i in range(n):
        c = U[0, i]
        cs = max(c, C_FLOOR)
        v = U[1, i] / cs if c > C_FLOOR else 0.0
        G = c * k[K_COS] + k[K_BAL]
        if column:
            G = G + push[i]
        if law == 3 and ve > 0:  # regularised Coulomb friction on the contact stress, TR-BDF2
            F = k[K_WALL] * _pj(c, jam, fr, cmin, cmax)[0]
            a = _BETA * dt
            ug = _solve_tanh(cs, a * F, cs * v + a * (G - F * math.tanh(v / ve)) + a * G, ve)
            v1 = _solve_tanh(cs, a * F, _A * cs * ug - (_A - 1.0) * cs * v + a * G, ve)
        elif law >= 1:
            if column:
                F = cap[i]
            elif law == 3:
                F = k[K_WALL] * _pj(c, jam, fr, cmin, cmax)[0]
            else:
                F = k[K_F0] * (c / k[K_C0] if law == 2 else 1.0)
            sgn = (1.0 if v > 0 else -1.0) if v != 0 else (1.0 if G >= 0 else -1.0)
            u, g = sgn * v, sgn * G
            Fs = k[K_STICK] * F  # static: the hold of a cell at rest
            u_free = u + dt * (g - F) / cs
            if u_free >= 0 and not (u == 0 and g <= Fs):
                u1 = u_free
            else:
                t_stop = u * cs / max(F - g, 1e-300) if g < F else math.inf
                rest = max(dt - t_stop, 0.0)
                u1 = 0.0 if abs(g) <= Fs else (g + F) * rest / cs
            v1 = sgn * u1
        else:
            a = 0.5 * dt * k[K_ALPHA]
            w = cs * v + dt * G - a * v * abs(v)
            sw = 1.0 if w > 0 else (-1.0 if w < 0 else 0.0)
            v1 = sw * 2 * abs(w) / (cs + math.sqrt(cs * cs + 4 * a * abs(w)))
        U[1, i] = c * v1 if c > C_FLOOR else 0.0


@njit(cache=True, error_model="numpy")
def _factor(lower, diag, upper):
    """LU factors of a tridiagonal matrix (``lower[i]`` at (i+1, i), ``upper[i]`` at (i, i+1)): the modified
    super-diagonal and the reciprocal pivots (multiplied by, not divided by, in each substitution). No
    pivoting: the diffusion matrices are column diagonally dominant."""
    n = diag.shape[0]
    cp = np.empty(n)
    inv = np.empty(n)
    inv[0] = 1.0 / diag[0]
    cp[0] = upper[0] * inv[0] if n > 1 else 0.0
    for i in range(1, n):
        inv[i] = 1.0 / (diag[i] - lower[i - 1] * cp[i - 1])
        cp[i] = upper[i] * inv[i] if i < n - 1 else 0.0
    return cp, inv


@njit(cache=True, error_model="numpy")
def _substitute(lower, cp, inv, rhs):
    n = inv.shape[0]
    x = np.empty(n)
    x[0] = rhs[0] * inv[0]
    for i in range(1, n):
        x[i] = (rhs[i] - lower[i - 1] * x[i - 1]) * inv[i]
    for i in range(n - 2, -1, -1):
        x[i] -= cp[i] * x[i + 1]
    return x


@njit(cache=True, error_model="numpy")
def _substitute2(lower, cp, inv, a, b):
    """:func:`_substitute` for two right-hand sides in one pass (the two recurrences overlap in the CPU)."""
    n = inv.shape[0]
    x = np.empty(n)
    y = np.empty(n)
    x[0] = a[0] * inv[0]
    y[0] = b[0] * inv[0]
    for i in range(1, n):
        x[i] = (a[i] - lower[i - 1] * x[i - 1]) * inv[i]
        y[i] = (b[i] - lower[i - 1] * y[i - 1]) * inv[i]
    for i in range(n - 2, -1, -1):
        x[i] -= cp[i] * x[i + 1]
        y[i] -= cp[i] * y[i + 1]
    return x, y


@njit(cache=True, error_model="numpy")
def _system(D, J, beta, h2, periodic):
    """The factored matrix ``I - beta L J`` (Sherman-Morrison for the periodic corners: the correction's
    vector ``u``), computed once for both TR-BDF2 stages."""
    n = J.shape[0]
    bh = beta / h2
    diag = np.empty(n)
    for i in range(n):
        diag[i] = 1 + bh * (D[i] + D[i + 1]) * J[i]
    upper = np.empty(n - 1)
    lower = np.empty(n - 1)
    for i in range(n - 1):
        upper[i] = -bh * D[i + 1] * J[i + 1]
        lower[i] = -bh * D[i + 1] * J[i]
    ct = cb = gam = 0.0
    u = np.zeros(n)
    if periodic:
        ct = -bh * D[0] * J[n - 1]
        cb = -bh * D[n] * J[0]
        gam = -diag[0]
        diag[0] -= gam
        diag[n - 1] -= cb * ct / gam
        u[0], u[n - 1] = gam, cb
    cp, inv = _factor(lower, diag, upper)
    return lower, cp, inv, u, ct, gam


@njit(cache=True, error_model="numpy")
def _sherman_morrison(y, z, ct, gam):
    """The periodic system's solution from ``y`` (the tridiagonal part's) and ``z`` (its solution for ``u``)."""
    n = y.shape[0]
    fac = (y[0] + ct / gam * y[n - 1]) / (1 + z[0] + ct / gam * z[n - 1])
    return y - fac * z


@njit(cache=True, error_model="numpy")
def _pressure(U, k, P):
    """The air pressure ``P0 r^gamma`` of every cell into ``P``."""
    for i in range(U.shape[1]):
        P[i] = k[K_P0] * _pow(U[2, i] / (1 - U[0, i]), k[K_GAMMA])


@njit(cache=True, error_model="numpy")
def _diffusion(U, dt, k, P):
    """TR-BDF2 step of the air's Darcy flux, as :meth:`Integrator.diffusion`; ``P`` holds the pressure of ``U``."""
    n = U.shape[1]
    bc = int(k[K_BC])
    c0, gam, K0, dx = k[K_C0], k[K_GAMMA], k[K_K0], k[K_DX]
    stokes = k[K_STOKES] != 0.0
    rk = np.empty(n)
    J = np.empty(n)
    kc0 = c0 * c0 / (1 - c0) ** 3
    for i in range(n):
        c, m = U[0, i], U[2, i]
        r = m / (1 - c)
        cs = max(c, C_FLOOR)
        rk[i] = r * K0 * ((1 - cs) ** 3 / (cs * cs)) * kc0
        if stokes:
            rk[i] *= 10 * cs / (1 + 9 * cs)
        J[i] = gam * P[i] / max(m, 1e-300)
    D = np.empty(n + 1)
    Pext = np.empty(n + 2)
    Pext[1:n + 1] = P
    if bc == 0:
        D[0] = 0.5 * (rk[n - 1] + rk[0])
        D[n] = D[0]
        Pext[0], Pext[n + 1] = P[n - 1], P[0]
    else:
        D[0], D[n] = rk[0], rk[n - 1]
        Pext[0] = Pext[n + 1] = k[K_PEND]
        if bc == 1:
            D[0] *= 2.0
            D[n] *= 2.0
            if k[K_SEAL] > 0:  # the air's way in crosses a column of packed grains too (Boundary.inlet_seal)
                D[0] = 1.0 / (1.0 / D[0] + k[K_SEAL] / dx)
        else:
            D[0] = D[n] = 0.0
    for f in range(1, n):
        D[f] = 0.5 * (rk[f - 1] + rk[f])
    LP = np.empty(n)
    h2 = dx * dx
    inv_h2 = 1.0 / h2
    for i in range(n):
        LP[i] = (D[i + 1] * (Pext[i + 2] - Pext[i + 1]) - D[i] * (Pext[i + 1] - Pext[i])) * inv_h2
    beta = _BETA * dt
    lower, cp, inv, u, ct, gam = _system(D, J, beta, h2, bc == 0)
    if bc == 0:  # the first stage and the corner correction's vector in one pass
        y, z = _substitute2(lower, cp, inv, _G2 * dt * LP, u)
        dg = _sherman_morrison(y, z, ct, gam)
        d = _sherman_morrison(_substitute(lower, cp, inv, _A * dg + beta * LP), z, ct, gam)
    else:
        dg = _substitute(lower, cp, inv, _G2 * dt * LP)
        d = _substitute(lower, cp, inv, _A * dg + beta * LP)
    for i in range(n):
        U[2, i] += d[i]


@njit(cache=True, error_model="numpy")
def max_speed(U, k):
    """The largest characteristic speed ``max |v + s±|`` of the cells."""
    P = np.empty(U.shape[1])
    _pressure(U, k, P)
    return _max_speed(U, P, k)


@njit(cache=True, error_model="numpy")
def _max_speed(U, P_cells, k):
    jam, fr, cmin, cmax = k[K_JAM] != 0.0, k[K_FR], k[K_CMIN], k[K_CMAX]
    best = 0.0
    for i in range(U.shape[1]):
        c = U[0, i]
        cs = max(c, C_FLOOR)
        v = U[1, i] / cs if c > C_FLOOR else 0.0
        P = P_cells[i]
        _, dpj = _pj(c, jam, fr, cmin, cmax)
        b = k[K_JTERM] * (v / (k[K_KAPPA] * cs))
        a = k[K_GAMMA] * P / (cs * (1 - c)) + dpj
        root = math.sqrt(b * b + 4 * a)
        here = max(abs(v + 0.5 * (b - root)), abs(v + 0.5 * (b + root)))
        if not math.isfinite(here):  # max() would drop a NaN: the blow-up must reach the time loop
            return math.nan
        best = max(best, here)
    return best


@njit(cache=True, error_model="numpy")
def _core(U, dt, k, Upad, W, acc):
    """Sources, fluxes, sources, as :meth:`Integrator._core`."""
    V = U.copy()
    _sources(V, 0.5 * dt, k)
    V = _hyperbolic(V, dt, k, Upad, W, acc)
    _sources(V, 0.5 * dt, k)
    return V


@njit(cache=True, error_model="numpy")
def step(U, dt, k):
    """One Strang step (diffusion, sources, fluxes, sources, diffusion), as :meth:`Integrator.step`."""
    n = U.shape[1]
    Upad = np.empty((3, n + 4))
    W = np.empty((4, n + 4))
    P = np.empty(n)
    V = U.copy()
    _pressure(V, k, P)
    _diffusion(V, 0.5 * dt, k, P)
    V = _core(V, dt, k, Upad, W, np.zeros(2))
    _pressure(V, k, P)
    _diffusion(V, 0.5 * dt, k, P)
    return V


@njit(cache=True, error_model="numpy")
def advance(U, t, t_end, cfl, k, acc):
    """Steps of CFL-limited length from ``t`` to exactly ``t_end``, consecutive diffusion half-steps merged, as
    :meth:`Integrator.advance`; returns the state, the time reached and the number of steps (stops early, the
    count negative, if the state blows up or the time step falls below ``k[K_DTMIN]``). The grain that enters
    and leaves an open pipe meanwhile is added to ``acc[0]`` and ``acc[1]``."""
    n = U.shape[1]
    Upad = np.empty((3, n + 4))
    W = np.empty((4, n + 4))
    P = np.empty(n)  # the pressure of the cells, shared by the speed and the diffusion
    U = U.copy()
    dx = k[K_DX]
    steps = 0
    owed = 0.0
    while t < t_end - 1e-12:
        _pressure(U, k, P)
        s = _max_speed(U, P, k)
        if not math.isfinite(s) or s <= 0:
            return U, t, -1 - steps
        dt = (k[K_STAGES] - 1) * cfl * dx / s
        if dt < k[K_DTMIN]:  # the model left its validity (the caller says where): stop, state finite
            return U, t, -1 - steps
        dt = min(dt, t_end - t)
        _diffusion(U, owed + 0.5 * dt, k, P)
        U = _core(U, dt, k, Upad, W, acc)
        owed = 0.5 * dt
        t += dt
        steps += 1
    if owed > 0:
        _pressure(U, k, P)
        _diffusion(U, owed, k, P)
    return U, t, steps
