"""The direction of the flow in the image, decided once, and the diagram turned to run with it."""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from ..calibration.tube import TubeGeometry
from ..diagram import Diagram, Normalized
from ..params import opposite, runs_backwards
from ..warning_codes import coded
from .grains import GrainMotion, falling_grains

log = logging.getLogger(__name__)


#: how :func:`resolve_flow` says it took the flow down a vertical tube for want of anything better
GRAVITY_DOWN = "assumed (gravity down)"

@dataclass(frozen=True)
class Flow:
    """The flow's direction in the image, how it was decided, and what is doubtful about it."""

    direction: str
    source: str
    warnings: tuple[str, ...] = ()

def falling(norm: Normalized, diagram: Diagram, fps: float, *,
            unseen: np.ndarray | None = None) -> GrainMotion | None:
    """The grains falling through the bubbles (None with one material only); ``unseen``: frames bridged by
    interpolation, whose pairs are left out (:func:`~grainplug.measures.grains.falling_grains`)."""
    if not norm.two_phase:
        return None
    ds = float(diagram.position_mm[1] - diagram.position_mm[0])
    return falling_grains(norm.z, mm_per_sample=ds, fps=fps, unseen=unseen)

def resolve_flow(given: str | None, tube: TubeGeometry, grains: GrainMotion | None) -> Flow:
    """The direction of the flow in the image, decided here and only here.

    The diagram is always streamed top to bottom (left to right); the flow runs the
    way the user said, else the way the grains fall through the bubbles, else down
    a vertical tube (gravity) and, with a warning, right along a horizontal one.
    """
    speed = None if grains is None else grains.speed_m_s  # positive: falling top to bottom / left to right
    forward = "down" if tube.orientation == "vertical" else "right"
    if given:
        warnings = ()
        if speed is not None and (speed < 0) != runs_backwards(given):
            warnings = (coded("flow.against_given",
                              f"the grains falling through the bubbles move against the given flow direction "
                              f"({given}; {abs(speed):.2f} m/s the other way): check the flow direction "
                              "(flow_direction=)"),)
            log.warning(warnings[0])
        return Flow(given, "user", warnings)
    if speed is not None:
        direction = opposite(forward) if speed < 0 else forward
        return Flow(direction, f"inferred from the grains falling through the bubbles ({abs(speed):.2f} m/s)")
    why = "one material only in the tube, no bubbles" if grains is None else grains.seen
    if tube.orientation == "vertical":
        return Flow(forward, f"{GRAVITY_DOWN}: {why}" if why else GRAVITY_DOWN)
    return Flow(forward, "assumed", (coded("flow.assumed", f"the grains falling through the bubbles give no "
                                           f"direction ({why}): the flow is assumed to run {forward}; if it does "
                                           "not, give the flow direction (flow_direction=)"),))


def assumed_down(source: str) -> str | None:
    """What was and was not seen (maybe ``""``) when ``source``, a :class:`Flow`'s, is gravity's assumption
    (the flow taken down a vertical tube for want of grains seen falling); None when it is not."""
    if source == GRAVITY_DOWN:
        return ""
    return source.removeprefix(f"{GRAVITY_DOWN}: ") if source.startswith(f"{GRAVITY_DOWN}: ") else None

def orient(diagram: Diagram, norm: Normalized, grains: GrainMotion | None, tube: TubeGeometry,
            direction: str) -> tuple[Diagram, Normalized, GrainMotion | None]:
    """Turn the diagram so that positions increase with the flow (a no-op for a flow down or right).

    Notes
    -----
    Streamed top to bottom, position :math:`s_i = (r_i + 1/2) / \\cos\\theta` for canonical
    row :math:`r_i`. Reversed, the distance from the bottom edge of an :math:`h`-row view is
    :math:`(h - 1 - r_i + 1/2)/\\cos\\theta = h/\\cos\\theta - s_i`, read in reverse order.
    """
    if not runs_backwards(direction):
        return diagram, norm, grains
    view_px = tube.canonical_shape[0] / np.cos(np.radians(tube.tilt_deg))
    d = dataclasses.replace(diagram, values=diagram.values[:, ::-1],
                            position_mm=view_px * diagram.mm_per_px - diagram.position_mm[::-1])
    n = dataclasses.replace(norm, z=norm.z[:, ::-1], position_gain=norm.position_gain[::-1])
    g = None if grains is None else dataclasses.replace(
        grains, speed_m_s=None if grains.speed_m_s is None else -grains.speed_m_s)
    return d, n, g
