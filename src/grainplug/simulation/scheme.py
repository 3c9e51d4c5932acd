"""Finite-volume integration of the conservative 1D model (NumPy reference).

Notes
-----
One time step of length ``dt`` is the symmetric (Strang) composition

.. math::

    \\mathcal D_{dt/2}\\, \\mathcal S_{dt/2}\\, \\mathcal H_{dt}\\, \\mathcal S_{dt/2}\\, \\mathcal D_{dt/2}

of three second-order parts, so the step is second order. Between two output times the
closing ``D_{dt_n/2}`` of a step and the opening ``D_{dt_{n+1}/2}`` of the next are done as
one ``D_{(dt_n + dt_{n+1})/2}``: exact for the exact flow of ``D``, a third-order local
difference for its second-order solver, so the run stays second order for half the
diffusion work (:meth:`Integrator.advance`). The parts:

- ``H``, the hyperbolic fluxes: MUSCL reconstruction of ``(c, v, P)`` and of the air
  density ``r`` with the monotonized-central limiter (``r`` and ``P`` are reconstructed
  separately, so a face needs no power ``P^(1/gamma)``, the costliest operation of the
  step; at a face they agree with ``P = P0 r^gamma`` to second order where the flow is
  smooth, and the flux stays consistent and conservative), the central-upwind numerical flux of Kurganov, Noelle &
  Petrova (2001) with the one-sided local speeds of :meth:`Closure.speeds`, and the
  optimal second-order strong-stability-preserving Runge-Kutta method of
  :data:`SSP_STAGES` stages, SSPRK(s,2): ``s - 1`` forward-Euler stages of
  ``dt / (s - 1)``, then ``U_new = U / s + (s - 1) / s (U_{s-1} + dt / (s - 1) L(U_{s-1}))``.
  Each stage is a forward-Euler step under the Courant number ``cfl``, so the step is
  ``s - 1`` times as long as one of Heun's method (``s = 2``) for ``s`` flux evaluations
  instead of two: half the flux work, and a third of the diffusion and source work, per
  unit time at ``s = 4``;
- ``D``, Darcy diffusion of the air mass, implicit (TR-BDF2 with ``gamma = 2 - sqrt 2``,
  L-stable, second order), the pressure linearised about the start of the sub-step;
  with the atmospheric base pressure it is stiff by a factor of a thousand;
- ``S``, gravity, the balance force and wall friction, cell by cell at fixed ``c``:
  Coulomb friction exactly (a stopped cell stays stopped while the driving force is
  below the friction: grains are never pushed upward by friction), the ``v|v|`` law by
  the trapezoidal rule solved in closed form.

Every part updates the conserved variables in flux form or leaves ``c`` and ``m``
untouched, so grain and air mass are conserved to round-off in a periodic box.

References
----------
A. Kurganov, S. Noelle, G. Petrova, SIAM J. Sci. Comput. 23 (2001) 707-740.
R. J. LeVeque, Finite Volume Methods for Hyperbolic Problems (CUP, 2002), ch. 6, 17.
R. E. Bank et al., IEEE Trans. CAD 4 (1985) 436 (TR-BDF2).
S. Gottlieb, D. I. Ketcheson, C.-W. Shu, Strong Stability Preserving Runge-Kutta and
Multistep Time Discretizations (World Scientific, 2011), §6.2 (SSPRK(s,2)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_banded

from .equations import C_FLOOR, Closure

_G2 = 2.0 - math.sqrt(2.0)
_BETA = _G2 / 2.0  # = (1 - g2) / (2 - g2): both TR-BDF2 stages share one matrix
_A = 1.0 / (_G2 * (2.0 - _G2))

#: how many ghost cells sit at each end of the padded arrays
N_GHOST = 2
#: stages of the SSPRK(s,2) method of the fluxes (its step is ``SSP_STAGES - 1`` Courant-limited stages long)
SSP_STAGES = 4


@dataclass(frozen=True)
class Boundary:
    """Boundary conditions.

    Attributes
    ----------
    kind : str
        ``"periodic"``; ``"open"``: an inlet at ``z = 0`` (the grain flux through the top
        face is the feed, ``inlet_c inlet_v``, exactly while the top cell is less dense than
        ``inlet_c``, else at most at the top grains' velocity: :func:`inlet_flux`; momentum and air fluxes come from
        the numerical flux against a ghost state holding the fed grains and air at
        ``P_end``) and a free outflow at ``z = L`` (zero-gradient ghosts: grains leave at
        their own velocity; the air pressure is held at ``P_end`` half a cell out); or
        ``"outflow"``: both ends free, no air flux through them (Riemann problems).
    inlet_c, inlet_v, P_end : float
        Inlet compactness and velocity, and the air pressure at both ends (dimensionless).
    inlet_seal : float
        Open pipe: the resistance of the air's way in at the top, ``H / (r K(c_h))`` for a column of ``H`` (in
        ``D``) of packed grains it must cross from the atmosphere (a hopper), in series with the half cell to the
        top face; 0 (default): the pressure is held at ``P_end`` at the top face.
    """

    kind: str = "periodic"
    inlet_c: float = 0.0
    inlet_v: float = 0.0
    P_end: float = 1.0
    inlet_seal: float = 0.0


def inlet_flux(c_top: float, v_top: float, c_feed: float, v_feed: float) -> float:
    """The grain flux an open pipe's top face takes from the feed: ``c_feed v_feed`` while the top cell is less
    dense than the feed, else ``c_feed`` times the top grains' velocity, between 0 and ``v_feed``.

    A hopper delivers its rate only while the grains below make room: fed grains cannot overtake a denser
    column under them. A prescribed flux into a column the walls hold at rest would pack the top cell to close
    packing, where the jamming pressure's wave speed, and with it the time step's limit, diverge (issue 37's
    stalled runs). The grain that enters is counted (``budget``), so the conservation check is unchanged."""
    if c_top < c_feed:
        return c_feed * v_feed
    return c_feed * min(max(v_top, 0.0), v_feed)


def column_stress(c: np.ndarray, weight: np.ndarray, wall: float, c_min: float, dx: float,
                  periodic: bool) -> tuple[np.ndarray, np.ndarray]:
    """Janssen's stress carried down each dense stretch: the force of its gradient on every cell, and the wall
    friction the cell can take (``WALL_STRESSES["janssen-column"]``).

    A dense stretch is a run of cells with ``c > c_min``. From its top face, where ``sigma = 0``, the stress obeys
    ``d sigma / dz = w - wall sigma`` (``w`` the weight per unit volume, ``wall = 4 mu_s kappa``: the walls fully
    mobilised), integrated exactly across each cell of constant ``w``. A cell's friction capacity is the mean of
    ``wall sigma`` over it, ``w - (sigma_below - sigma_above) / dx``, and the stress's gradient pushes it with
    ``-(sigma_below - sigma_above) / dx``: inside a stretch the weight and that push are exactly the capacity (a
    cell at rest stays, at Coulomb's limit). At the stretch's free bottom nothing pushes back, ``sigma = 0`` below
    its lowest cell: that cell is pushed by the stress above it, ``sigma / dx`` more than its walls hold, and is
    released. A periodic box that is dense all round carries the periodic solution (no top, no bottom).

    Parameters
    ----------
    c, weight : ndarray, shape (n,)
        The compactness and the weight ``c cos(theta)`` of the cells.
    wall : float
        ``4 mu_s kappa`` (per ``D``).
    c_min : float
        The compactness above which grains touch (random loose packing).
    dx : float
    periodic : bool

    Returns
    -------
    push, capacity : ndarray, shape (n,)
        The force of the stress gradient (positive downward) and the largest wall friction, per unit volume.
    """
    n = c.shape[0]
    decay = math.exp(-wall * dx)
    gain = (1.0 - decay) / wall
    push = np.zeros(n)
    cap = np.zeros(n)
    dense = c > c_min
    if not dense.any():
        return push, cap
    if dense.all() and periodic:  # sigma_0 = decay^n sigma_0 + sum_j decay^(n-1-j) gain w_j
        s = float(np.sum(weight * gain * decay ** np.arange(n - 1, -1, -1))) / (1.0 - decay**n)
        for i in range(n):
            s_next = decay * s + weight[i] * gain
            push[i] = -(s_next - s) / dx
            cap[i] = weight[i] + push[i]
            s = s_next
        return push, cap
    start = int(np.argmin(dense)) if periodic else 0  # a dilute cell (periodic): no stretch crosses the start
    s = 0.0
    for t in range(n):
        i = (start + t) % n
        if not dense[i]:
            s = 0.0
            continue
        s_next = decay * s + weight[i] * gain
        cap[i] = weight[i] - (s_next - s) / dx
        j = i + 1 if i + 1 < n else (0 if periodic else -1)
        last = j < 0 or not dense[j] or (periodic and t == n - 1)
        push[i] = s / dx if last else -(s_next - s) / dx
        s = s_next
    return push, cap


def _solve_tanh(c: np.ndarray, aF: np.ndarray, R: np.ndarray, ve: float) -> np.ndarray:
    """The root ``u`` of ``c u + aF tanh(u / ve) = R`` (increasing in ``u``: one root, bracketed by
    ``(R -+ aF) / c``), by Newton's method kept inside the bracket (bisection when a step leaves it), started
    from the sliding root ``(R - sgn(R) aF) / c`` where ``|R| > aF``, else from the stuck (linear) one: a few
    iterations where the plain linear start took 20-60 (the kernel's cost grew 27-fold)."""
    lo, hi = (R - aF) / c, (R + aF) / c
    u = np.where(np.abs(R) > aF, (R - np.copysign(aF, R)) / c, R / (c + aF / ve))
    active = np.ones(u.shape, bool)
    for _ in range(200):
        t = np.tanh(u / ve)
        g = c * u + aF * t - R
        active &= g != 0
        hi = np.where(active & (g > 0), u, hi)
        lo = np.where(active & (g <= 0), u, lo)
        un = u - g / (c + aF * (1 - t * t) / ve)
        un = np.where((un > lo) & (un < hi), un, 0.5 * (lo + hi))
        done = np.abs(un - u) <= 1e-15 * np.maximum(np.abs(un), ve)
        u = np.where(active, un, u)
        active &= ~done
        if not active.any():
            break
    return u


def _regularised_coulomb(c: np.ndarray, v: np.ndarray, G: np.ndarray, F: np.ndarray, ve: float,
                         dt: float) -> np.ndarray:
    """``c v' = G - F tanh(v / ve)`` over ``dt`` at fixed ``c`` by TR-BDF2 (L-stable and second order: the
    friction is stiff, ``F / (c ve)`` reaches 10^3 / t_c): the velocity after ``dt``."""
    a = _BETA * dt  # both stages: c u + a F tanh(u / ve) = R
    ug = _solve_tanh(c, a * F, c * v + a * (G - F * np.tanh(v / ve)) + a * G, ve)
    return _solve_tanh(c, a * F, _A * c * ug - (_A - 1.0) * c * v + a * G, ve)


def _mc_slopes(w: np.ndarray) -> np.ndarray:
    """Monotonized-central limited slopes of the cells ``1 .. n-2`` of ``w`` (last axis)."""
    d = np.diff(w, axis=-1)
    dl, dr = d[..., :-1], d[..., 1:]
    s = np.minimum(np.minimum(2 * np.abs(dl), 2 * np.abs(dr)), 0.5 * np.abs(dl + dr))
    return np.where(dl * dr > 0, np.copysign(s, dl), 0.0)


class Integrator:
    """Advance ``U = (c, q, m)`` on a uniform grid of ``n`` cells of width ``dx``.

    Parameters
    ----------
    closure : Closure
    n : int
        Number of cells.
    dx : float
        Cell width (units of ``D``).
    boundary : Boundary
    """

    def __init__(self, closure: Closure, n: int, dx: float, boundary: Boundary | None = None, *,
                 dt_floor: float = 0.0) -> None:
        self.cl = closure
        self.dt_floor = dt_floor
        self.n = n
        self.dx = dx
        self.bc = boundary or Boundary()
        self.periodic = self.bc.kind == "periodic"
        # inlet ghost state (open pipe)
        self.inlet = np.array([self.bc.inlet_c, self.bc.inlet_c * self.bc.inlet_v,
                                float(closure.air_density(np.array(self.bc.P_end))) * (1 - self.bc.inlet_c)])

    # -- ghost cells ---------------------------------------------------------------
    def pad(self, U: np.ndarray) -> np.ndarray:
        g = N_GHOST
        if self.periodic:
            return np.concatenate([U[:, -g:], U, U[:, :g]], axis=1)
        # inlet: the fed grains with air at the end pressure; outlet: copy the last cell
        # (zero gradient) so that grains and air leave freely
        left = (np.repeat(U[:, :1], g, axis=1) if self.bc.kind == "outflow"
                else np.repeat(self.inlet[:, None], g, axis=1))
        right = np.repeat(U[:, -1:], g, axis=1)
        return np.concatenate([left, U, right], axis=1)

    # -- hyperbolic part --------------------------------------------------------------
    def max_speed(self, U: np.ndarray) -> float:
        c, v, P = self.cl.primitive(U)
        lo, hi = self.cl.speeds(c, v, P)
        return float(max(np.max(np.abs(lo)), np.max(np.abs(hi))))

    def face_fluxes(self, U: np.ndarray) -> np.ndarray:
        """Central-upwind fluxes at the ``n + 1`` faces of the cells (shape ``(3, n + 1)``)."""
        cl = self.cl
        Up = self.pad(U)
        c, v, P = cl.primitive(Up)
        W = np.stack([c, v, P, np.maximum(Up[2] / (1 - c), 0.0)])  # r too: no power at the faces
        s = _mc_slopes(W)  # cells 1 .. n+2 of the padded array
        wl = W[:, 1:-2] + 0.5 * s[:, :-1]  # left state at the faces between cells i, i+1 (i = 1 .. n+1)
        wr = W[:, 2:-1] - 0.5 * s[:, 1:]
        wl[0] = np.clip(wl[0], 0.0, 1.0 - 1e-9)
        wr[0] = np.clip(wr[0], 0.0, 1.0 - 1e-9)
        lo_l, hi_l = cl.speeds(*wl[:3])
        lo_r, hi_r = cl.speeds(*wr[:3])
        ap = np.maximum(np.maximum(hi_l, hi_r), 0.0)
        am = np.minimum(np.minimum(lo_l, lo_r), 0.0)
        fl, fr = cl.flux(*wl), cl.flux(*wr)
        ul = np.stack([wl[0], wl[0] * wl[1], wl[3] * (1 - wl[0])])
        ur = np.stack([wr[0], wr[0] * wr[1], wr[3] * (1 - wr[0])])
        span = ap - am
        span = np.where(span > 0, span, 1.0)
        H = (ap * fl - am * fr + ap * am * (ur - ul)) / span
        if self.bc.kind == "open":  # the feed: the fed grains enter while the top cell has room
            c_top = float(U[0, 0])
            v_top = float(U[1, 0]) / c_top if c_top > C_FLOOR else 0.0
            H[0, 0] = inlet_flux(c_top, v_top, self.bc.inlet_c, self.bc.inlet_v)
        return H

    def hyperbolic_rate(self, U: np.ndarray, budget: np.ndarray | None = None, weight: float = 0.0) -> np.ndarray:
        """The flux divergence ``-(H[f+1] - H[f]) / dx`` of every cell; adds ``weight`` times the grain flux
        through the first and the last face to ``budget[0]`` and ``budget[1]`` (an open pipe's inflow and
        outflow)."""
        H = self.face_fluxes(U)
        if budget is not None and not self.periodic:
            budget[0] += weight * H[0, 0]
            budget[1] += weight * H[0, -1]
        return -(H[:, 1:] - H[:, :-1]) / self.dx

    def hyperbolic(self, U: np.ndarray, dt: float, budget: np.ndarray | None = None) -> np.ndarray:
        """The SSPRK(s,2) step of the fluxes (``s`` = :data:`SSP_STAGES`).

        With ``budget``, the grain that crossed the ends over the step is added to it: the step changes
        ``sum(c) dx`` by ``dt / s`` times the sum over its ``s`` stages of the inflow minus the outflow,
        exactly, as long as no compactness is clipped to ``[0, 1)``."""
        s = SSP_STAGES
        h = dt / (s - 1)
        V = U
        for _ in range(s - 1):
            V = V + h * self.hyperbolic_rate(V, budget, dt / s)
            V[0] = np.clip(V[0], 0.0, 1.0 - 1e-9)
        out = U / s + (s - 1) / s * (V + h * self.hyperbolic_rate(V, budget, dt / s))
        out[0] = np.clip(out[0], 0.0, 1.0 - 1e-9)
        return out

    # -- sources ---------------------------------------------------------------------
    def sources(self, U: np.ndarray, dt: float) -> np.ndarray:
        """Gravity, the balance force and wall friction over ``dt`` at fixed ``c`` and ``m``."""
        cl = self.cl
        c, q, m = U
        cs = np.maximum(c, C_FLOOR)
        v = np.where(c > C_FLOOR, q / cs, 0.0)
        G = c * cl.cos_theta + cl.balance_force  # driving force per unit volume
        if cl.law == "coulomb-janssen" and cl.v_eps > 0:
            v1 = _regularised_coulomb(cs, v, G, cl.wall * cl.jamming_pressure(c), cl.v_eps, dt)
        elif cl.law.startswith("coulomb"):
            if cl.column:  # Janssen's stress carried down each dense stretch: its gradient's push, the walls' hold
                push, F = column_stress(c, c * cl.cos_theta, cl.wall, cl.jam_c_min, self.dx, self.periodic)
                G = G + push
            elif cl.law == "coulomb-janssen":
                F = cl.wall * cl.jamming_pressure(c)
            else:
                F = cl.F0 * (c / cl.c0 if cl.law == "coulomb-weight" else 1.0) * np.ones_like(c)
            sgn = np.where(v != 0, np.sign(v), np.where(G >= 0, 1.0, -1.0))
            u, g = sgn * v, sgn * G  # mirrored so that u >= 0
            Fs = cl.stick * F  # static friction: the hold of a cell at rest (kinetic F while it slides)
            u_free = u + dt * (g - F) / cs
            t_stop = np.where(g < F, u * cs / np.maximum(F - g, 1e-300), np.inf)
            rest = np.maximum(dt - t_stop, 0.0)
            # at rest (from the start or after stopping): stays while |g| <= Fs, else slides (kinetic F)
            u_after = np.where(np.abs(g) <= Fs, 0.0, (g + F) * rest / cs)
            u1 = np.where((u_free >= 0) & ~((u == 0) & (g <= Fs)), u_free, u_after)
            v1 = sgn * u1
        else:  # v|v| (the printed v^2 law given the sign of v), trapezoidal rule
            a = 0.5 * dt * cl.alpha
            w = cs * v + dt * G - a * v * np.abs(v)
            v1 = np.sign(w) * 2 * np.abs(w) / (cs + np.sqrt(cs * cs + 4 * a * np.abs(w)))
        return np.stack([c, np.where(c > C_FLOOR, c * v1, 0.0), m])

    # -- air diffusion ------------------------------------------------------------------
    def _diffusion_parts(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Face coefficients ``D`` (``n + 1`` faces), ``J = dP/dm`` of the cells, and ``P`` padded with the ends."""
        cl = self.cl
        c, _, m = U
        r = m / (1 - c)
        P = cl.pressure(r)
        rk = r * cl.permeability(c)
        if self.periodic:
            rk_ext = np.concatenate([rk[-1:], rk, rk[:1]])
            P_ext = np.concatenate([P[-1:], P, P[:1]])
        else:  # the ends are held at P_end, half a cell outside the first and last cells
            rk_ext = np.concatenate([rk[:1], rk, rk[-1:]])
            P_ext = np.concatenate([[self.bc.P_end], P, [self.bc.P_end]])
        D = 0.5 * (rk_ext[:-1] + rk_ext[1:])
        if self.bc.kind == "open":
            D[[0, -1]] *= 2.0  # the held pressure is half a cell away
            if self.bc.inlet_seal > 0:  # ... and at the top, beyond a column of packed grains too (in series)
                D[0] = 1.0 / (1.0 / D[0] + self.bc.inlet_seal / self.dx)
        elif self.bc.kind == "outflow":
            D[[0, -1]] = 0.0
        J = cl.gamma * P / np.maximum(m, 1e-300)
        return D, J, P_ext

    def _laplacian(self, D: np.ndarray, x_ext: np.ndarray) -> np.ndarray:
        flux = -D * np.diff(x_ext) / self.dx
        return -(flux[1:] - flux[:-1]) / self.dx

    def _solve(self, D: np.ndarray, J: np.ndarray, beta: float, rhs: np.ndarray) -> np.ndarray:
        """Solve ``(I - beta L J) x = rhs`` (``L`` the flux-form operator, ``x`` zero at held ends)."""
        n, h2 = self.n, self.dx * self.dx
        dl, dr = D[:-1], D[1:]  # faces left and right of each cell
        diag = 1 + beta * (dl + dr) * J / h2
        upper = -beta * dr[:-1] * J[1:] / h2  # (i, i+1)
        lower = -beta * dl[1:] * J[:-1] / h2  # (i+1, i)
        if not self.periodic:
            ab = np.zeros((3, n))
            ab[0, 1:], ab[1], ab[2, :-1] = upper, diag, lower
            return solve_banded((1, 1), ab, rhs)
        corner_top = -beta * dl[0] * J[-1] / h2  # (0, n-1)
        corner_bottom = -beta * dr[-1] * J[0] / h2  # (n-1, 0)
        # Sherman-Morrison: A = T + u v^T
        gam = -diag[0]
        d = diag.copy()
        d[0] -= gam
        d[-1] -= corner_bottom * corner_top / gam
        ab = np.zeros((3, n))
        ab[0, 1:], ab[1], ab[2, :-1] = upper, d, lower
        u = np.zeros(n)
        u[0], u[-1] = gam, corner_bottom
        sol = solve_banded((1, 1), ab, np.stack([rhs, u], axis=1))
        y, z = sol[:, 0], sol[:, 1]
        fac = (y[0] + corner_top / gam * y[-1]) / (1 + z[0] + corner_top / gam * z[-1])
        return y - fac * z

    def diffusion(self, U: np.ndarray, dt: float) -> np.ndarray:
        """TR-BDF2 step of the air's Darcy flux (the increments are flux differences: air is conserved)."""
        D, J, P_ext = self._diffusion_parts(U)
        LP = self._laplacian(D, P_ext)
        beta = _BETA * dt
        dg = self._solve(D, J, beta, _G2 * dt * LP)
        d = self._solve(D, J, beta, _A * dg + beta * LP)
        out = U.copy()
        out[2] = U[2] + d
        return out

    # -- steps --------------------------------------------------------------------
    def advance(self, U: np.ndarray, t: float, t_end: float, cfl: float,
                budget: np.ndarray | None = None) -> tuple[np.ndarray, float, int]:
        """Steps of CFL-limited length from ``t`` to exactly ``t_end``: the state, the time reached and the
        number of steps (negative, with the time it stopped, when the state blew up or the time step fell
        below ``dt_floor``), as
        :func:`grainplug.simulation._kernel.advance`. The grain that enters and leaves an open pipe
        meanwhile is added to ``budget[0]`` and ``budget[1]`` (see :meth:`hyperbolic`).

        The steps are :meth:`step`, with the closing air-diffusion half-step of one step and the opening
        one of the next merged into one ``D_{(dt_n + dt_{n+1})/2}`` (the diffusion is the costliest part
        after the fluxes); the Courant limit of a step is taken on the state before that merged diffusion."""
        steps = 0
        owed = 0.0  # the closing diffusion half-step of the previous step, not yet done
        while t < t_end - 1e-12:
            speed = self.max_speed(U)
            if not math.isfinite(speed) or speed <= 0:
                return U, t, -1 - steps
            dt = (SSP_STAGES - 1) * cfl * self.dx / speed
            if dt < self.dt_floor:  # the model left its validity: stop (the caller says where)
                return U, t, -1 - steps
            dt = min(dt, t_end - t)
            U = self.diffusion(U, owed + 0.5 * dt)
            U = self._core(U, dt, budget)
            owed = 0.5 * dt
            t += dt
            steps += 1
        if owed > 0:
            U = self.diffusion(U, owed)
        return U, t, steps

    def _core(self, U: np.ndarray, dt: float, budget: np.ndarray | None = None) -> np.ndarray:
        """Sources, fluxes, sources: the middle of :meth:`step`."""
        U = self.sources(U, 0.5 * dt)
        U = self.hyperbolic(U, dt, budget)
        return self.sources(U, 0.5 * dt)

    def step(self, U: np.ndarray, dt: float) -> np.ndarray:
        """One Strang-split step of length ``dt``: ``D_{dt/2} S_{dt/2} H_dt S_{dt/2} D_{dt/2}``."""
        U = self.diffusion(U, 0.5 * dt)
        U = self._core(U, dt)
        return self.diffusion(U, 0.5 * dt)
