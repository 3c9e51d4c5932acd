"""Linear stability of the compact base state: normal-mode matrix, cubic, roots.

Notes
-----
Perturbations ``(c~, v~, P~) exp(i (k* z* - omega* t*))`` of the base state
``c = c0, v* = 1, P* = 1`` satisfy ``M(k*, omega*) (c^, v^, P^) = 0`` with the
matrix printed in the paper (eq. "eigenvalue"),

.. math::

    M = \\begin{pmatrix}
        i k - i\\omega & i k c_0 & 0 \\\\
        -\\cos\\theta & -i\\omega c_0 + i k c_0 + i k/\\kappa + 4 b \\mu_s & i k \\\\
        0 & \\frac{\\gamma}{1 - c_0} i k & -i\\omega + i k + B_1^* k^2
    \\end{pmatrix}

(stars dropped). For another set-up (:class:`ModelParams`: base pressure ``P0*``,
base velocity ``v0*``, friction law ``F(c, v)``) the same linearisation gives

.. math::

    M = \\begin{pmatrix}
        i k v_0 - i\\omega & i k c_0 & 0 \\\\
        -\\cos\\theta + F_c + i k p_j' & -i\\omega c_0 + i k c_0 v_0 + i k v_0/\\kappa + F_v & i k \\\\
        0 & \\frac{\\gamma P_0}{1 - c_0} i k & -i\\omega + i k v_0 + B_1^* P_0 k^2
    \\end{pmatrix}

with ``F_c, F_v`` the derivatives of ``F`` at the base state (printed: ``F = 2 b mu_s v^2``,
``F_v = 4 b mu_s``, ``F_c = 0``) and ``p_j'`` the slope of the optional jamming pressure;
``tests/test_stability.py`` derives it with sympy for
every set-up. ``M = A(k) - i omega E`` with ``E = diag(1, c0, 1)``, so the
three roots of ``det M = 0`` (the cubic of eq. "det") are
``omega = -i lambda`` for the eigenvalues ``lambda`` of ``E^-1 A(k)``: this is how
they are computed, for all wavenumbers at once. ``omega = omega_r + i omega_i``;
``omega_i`` (in units of ``1/t_c``) is the growth rate and ``omega_r / k`` the
phase speed (in units of ``v_c``). The paper writes ``omega_r* = omega_r/(k v_c)``,
which is this phase speed; here ``omega*`` is ``omega t_c`` throughout.

Each root is followed continuously along ``k*``: consecutive roots are matched
by the permutation that moves them least. Roots are numbered by decreasing
growth rate at the smallest ``k*``.

References
----------
C. A. Alvarez, E. M. Franklin, Intermittent gravity-driven flow of grains
through narrow pipes, Physica A 465 (2017) 725-741, eqs. (11)-(15).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from .params import ModelParams

_PERMS = np.array(list(itertools.permutations(range(3))))


def _theta(p: ModelParams) -> float:
    return math.radians(p.theta_deg)


def system_matrices(p: ModelParams, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A(k)`` (shape ``(n, 3, 3)``) and ``E`` with ``M(k, omega) = A(k) - i omega E``."""
    k = np.atleast_1d(np.asarray(k, dtype=float))
    n = k.size
    A = np.zeros((n, 3, 3), complex)
    ik = 1j * k
    v0, P0 = p.v0_star, p.P0_star
    A[:, 0, 0] = ik * v0
    A[:, 0, 1] = ik * p.c0
    A[:, 1, 0] = -math.cos(_theta(p)) + p.friction_c + ik * p.jamming_slope
    janssen = ik * v0 / p.kappa if p.janssen_v2_term else 0.0  # the paper's (v / kappa) v_z, or dropped
    A[:, 1, 1] = ik * p.c0 * v0 + janssen + p.friction
    A[:, 1, 2] = ik
    A[:, 2, 1] = p.gamma * P0 / (1 - p.c0) * ik
    A[:, 2, 2] = ik * v0 + p.B_star * k**2
    E = np.diag([1.0, p.c0, 1.0]).astype(complex)
    return A, E


def normal_mode_matrix(p: ModelParams, k: float | np.ndarray, omega: complex | np.ndarray) -> np.ndarray:
    """The 3x3 normal-mode matrix ``M(k*, omega*)`` of eq. "eigenvalue" (broadcast over inputs)."""
    k_arr, w_arr = np.broadcast_arrays(np.asarray(k, float), np.asarray(omega, complex))
    A, E = system_matrices(p, k_arr.ravel())
    M = A - 1j * w_arr.ravel()[:, None, None] * E
    return M.reshape(*k_arr.shape, 3, 3)


def dispersion_coefficients(p: ModelParams, k: float | np.ndarray) -> np.ndarray:
    """Coefficients ``(a3, a2, a1, a0)`` of the cubic ``a3 w^3 + a2 w^2 + a1 w + a0 = 0``, eq. "det".

    Transcribed from the printed equation (with ``4 mu_s`` read as the friction
    coefficient of the variant, ``4 b mu_s`` or 0). It holds for the printed base state
    (``v* = 1, P* = 1``, no friction on ``c~``); other set-ups' roots come from the matrix.
    """
    if (p.v0_star != 1.0 or p.P0_star != 1.0 or p.friction_c != 0.0 or p.jamming_slope != 0.0
            or not p.janssen_v2_term or p.drag != "carman-kozeny"):
        from ..errors import ParameterError

        raise ParameterError("the printed cubic holds for the printed base state only (v* = 1, P* = 1, friction "
                             "not following c): use roots(), which solves the matrix of any set-up")
    k = np.asarray(k, dtype=float)
    c0, kinv, B, g = p.c0, 1.0 / p.kappa, p.B1_star, p.gamma
    cos = math.cos(_theta(p))
    f = p.friction  # 4 mu_s in the printed equation
    a3 = np.full(k.shape, 1j * c0)
    a2 = k * (-3j * c0 - 1j * kinv) - k**2 * c0 * B - f
    a1 = (k**3 * (2 * c0 * B + kinv * B) + 1j * k**2 * (2 * kinv - g / (1 - c0) + 3 * c0 - f * B)
          + k * (c0 * cos + 2 * f))
    a0 = (1j * k**3 * (-c0 - kinv + f * B + c0 * cos * B + g / (1 - c0))
          + k**2 * (-f - c0 * cos) + B * k**4 * (-kinv - c0))
    return np.stack(np.broadcast_arrays(a3, a2, a1, a0), axis=-1)


_PERM_INDEX = {tuple(q): i for i, q in enumerate(_PERMS.tolist())}


def _composition_table() -> np.ndarray:
    """``T[a, b]`` = index of the permutation ``PERMS[a][PERMS[b]]``."""
    return np.array([[_PERM_INDEX[tuple(_PERMS[a][_PERMS[b]])] for b in range(6)] for a in range(6)])


_COMPOSE = _composition_table()
_COMPOSE_LIST: list[list[int]] = _COMPOSE.tolist()


#: wavenumbers solved at a time: about 1.2 kB of working arrays each, so ~5 MB a chunk, whatever the count
CHUNK_SIZE = 4096
#: bytes of working arrays per wavenumber of a chunk (matrices, eigenvalues, the matching's distances), measured
WORK_BYTES_PER_K = 1200


def roots(p: ModelParams, k: np.ndarray, *, track: bool = True, chunk_size: int = CHUNK_SIZE) -> np.ndarray:
    """The three roots ``omega*(k*)``, shape ``(n_k, 3)``.

    Parameters
    ----------
    p : ModelParams
    k : array_like
        Dimensionless wavenumbers ``k* = k D`` (sorted, when ``track``).
    track : bool
        Follow each root continuously along ``k``; the columns are numbered by
        decreasing growth rate at the first ``k``.
    chunk_size : int
        Wavenumbers solved at a time: the working memory is about 1.2 kB each on top
        of the result's 48 B per wavenumber. The roots do not depend on it.
    """
    k = np.atleast_1d(np.asarray(k, dtype=float))
    chunk_size = max(int(chunk_size), 1)
    out = np.empty((k.size, 3), complex)
    if not track:
        for i0 in range(0, k.size, chunk_size):
            out[i0:i0 + chunk_size] = _raw_roots(p, k[i0:i0 + chunk_size])
        if k.size:
            out[0] = out[0][_first_order(out[0])]
        return out
    tracker = _RootTracker()
    for i0 in range(0, k.size, chunk_size):
        out[i0:i0 + chunk_size] = tracker.follow(_raw_roots(p, k[i0:i0 + chunk_size]))
    return out


def _raw_roots(p: ModelParams, k: np.ndarray) -> np.ndarray:
    """The roots at each ``k`` in the eigensolver's order, shape ``(n, 3)``."""
    A, E = system_matrices(p, k)
    return -1j * np.linalg.eigvals(A / np.diag(E)[None, :, None])  # omega = -i eig(E^-1 A)


def _first_order(w: np.ndarray) -> np.ndarray:
    """The order of one wavenumber's roots by decreasing growth rate."""
    return np.argsort(-w.imag, kind="stable")


class _RootTracker:
    """Follows the three roots along ``k`` across consecutive chunks of wavenumbers.

    Consecutive roots are matched by the permutation that moves them least; the
    tracker carries the last wavenumber's roots and order from one chunk to the
    next, so that chunks give the same columns as one call on all the wavenumbers.
    """

    def __init__(self) -> None:
        self._last: np.ndarray | None = None  # the previous chunk's last raw roots, shape (3,)
        self._acc = 0  # index in _PERMS of the tracked order at that wavenumber

    def follow(self, raw: np.ndarray) -> np.ndarray:
        """The roots ``raw`` (shape ``(n, 3)``, the eigensolver's order) in tracked order."""
        if len(raw) == 0:
            return raw.copy()
        if self._last is None:
            self._acc = _PERM_INDEX[tuple(_first_order(raw[0]).tolist())]
            ext, sigma0 = raw, []
        else:
            ext, sigma0 = np.concatenate([self._last[None, :], raw]), None
        # pi_j: the permutation with ext[j+1][pi_j] closest to ext[j]; d[j, a, b] = |ext[j+1][a] - ext[j][b]|
        d = np.abs(ext[1:][:, :, None] - ext[:-1][:, None, :])
        P = _PERMS
        cost = d[:, P[:, 0], 0] + d[:, P[:, 1], 1] + d[:, P[:, 2], 2]
        best = np.argmin(cost, axis=1).tolist()
        # sigma_{j+1} = pi_j[sigma_j]: the tracked order of each step
        table = _COMPOSE_LIST
        acc = self._acc
        sigma = [acc] if sigma0 is not None else []
        for b in best:
            acc = table[b][acc]
            sigma.append(acc)
        self._acc = acc
        self._last = raw[-1].copy()
        return np.take_along_axis(raw, _PERMS[np.array(sigma, dtype=np.intp)], axis=1)
