"""What the analysis can be told: :class:`AnalysisParams`, and the flow-direction convention.

Flow directions are defined here and nowhere else: the analysis
(:mod:`grainplug.pipeline`), the synthetic movies and the command line all take
them from :data:`FLOW_DIRECTIONS`.
"""

from __future__ import annotations

import dataclasses
import decimal
import math
import numbers
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .errors import ParameterError

if TYPE_CHECKING:
    from .calibration.background import Background
    from .calibration.pattern import Calibration

#: directions of the grain flow in the image
FLOW_DIRECTIONS = ("down", "up", "left", "right")


@dataclass(frozen=True)
class Range:
    """Where a number must lie, and its unit, for the messages that refuse it."""

    lo: float
    hi: float
    unit: str = ""
    integer: bool = False

    def holds(self, value: object) -> bool:
        """Whether ``value`` is a finite number within the range (and whole, for an integer)."""
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
            return False
        if self.integer and float(value) != int(value):
            return False
        return self.lo <= float(value) <= self.hi

    def message(self, value: object) -> str:
        whole = "a whole number " if self.integer else ""
        unit = f" {self.unit}" if self.unit else ""
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            return f"must be a number{unit and ' (' + unit.strip() + ')'}, got {value!r} (a {type(value).__name__})"
        return f"must be {whole}between {self.lo:g} and {self.hi:g}{unit}, got {value}"


def as_number(value: object) -> object:
    """``value`` as a plain Python number where it is one in another dress (a numpy scalar, a 0-d array, a
    Decimal or Fraction), else unchanged (a string stays a string, to be refused by name)."""
    if value is None or isinstance(value, (str, bytes, bool)):
        return value
    if getattr(value, "shape", None) == () and hasattr(value, "item"):
        value = value.item()
    if isinstance(value, bool):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, (numbers.Real, decimal.Decimal)):
        try:
            return float(value)
        except ValueError:  # a signalling NaN Decimal: not a number, refused by name
            return value
    return value


#: the one table of ranges: :class:`AnalysisParams` checks them, the command line's options
#: (:class:`grainplug.cli.types.Number`) and the manifests' columns take them from here
RANGES: dict[str, Range] = {
    "fps": Range(1, 1e7, "frames per second"),
    "mm_per_px": Range(1e-5, 100, "mm per pixel"),
    "tube_diameter_mm": Range(0.05, 1000, "mm"),
    "tube_outer_diameter_mm": Range(0.05, 2000, "mm"),
    "glass_index": Range(1.3, 2.0, "(a glass's refractive index)"),
    "min_plug_mm": Range(0.01, 1e4, "mm"),
    "min_gap_mm": Range(0, 1e4, "mm"),
    "sample_frames": Range(4, 10_000, "frames", integer=True),
    "packed_compactness": Range(0.05, 0.95, "(a packing's volume fraction)"),
    "grain_density_kg_m3": Range(100, 25000, "kg/m^3 (the grains' material, e.g. glass 2500)"),
}


def checked_fps(fps: object) -> float | None:
    """A frame rate given by the user as a float (None stays None), or :class:`ParameterError` naming it."""
    value = as_number(fps)
    if value is not None and not RANGES["fps"].holds(value):
        raise ParameterError(RANGES["fps"].message(value) + " — give the camera's frame rate", param="fps")
    return None if value is None else float(value)  # type: ignore[arg-type]


def tube_orientation(direction: str) -> str:
    """``"vertical"`` for a flow up or down the image, ``"horizontal"`` for left or right."""
    return "vertical" if direction in ("down", "up") else "horizontal"


def runs_backwards(direction: str) -> bool:
    """Whether a flow runs towards decreasing image rows (up) or columns (left)."""
    return direction in ("up", "left")


def opposite(direction: str) -> str:
    """The other way along the same tube."""
    return {"down": "up", "up": "down", "left": "right", "right": "left"}[direction]


@dataclass(frozen=True)
class AnalysisParams:
    """Every tunable of :func:`grainplug.analyze` (all optional).

    Attributes
    ----------
    fps : float, optional
        Frame rate overriding the file's (required for image folders and arrays).
    mm_per_px : float, optional
        Scale; without it the scale comes from the tube's inner width.
    tube_diameter_mm : float
        Inner diameter of the tube (3 mm in the paper).
    tube_outer_diameter_mm : float, optional
        Outer diameter of the tube (glass tubing is sold by both): the scale then
        comes from the tube's outer silhouette, which no lighting changes, checked
        against its refraction stripes.
    glass_index : float
        Refractive index of the tube's glass (1.47 borosilicate; 1.52 soda-lime),
        for the tube model.
    flow_direction : {"down", "up", "left", "right"}, optional
        Direction of the grain flow in the image. By default it is read from
        the grains falling through the bubbles; when none are seen, down for a
        vertical tube and right for a horizontal one (the summary says which).
    min_plug_mm : float
        Shortest grain region counted as a plug (the paper's 3 mm).
    min_gap_mm : float
        Shortest gap between grains counted as a bubble.
    sample_frames : int
        Frames sampled over the movie to find the tube.
    glob : str, optional
        For image folders: only files matching this pattern.
    allow_truncated : bool
        For camera files that end early: analyse the complete frames (with a warning)
        instead of refusing the file.
    calibration : Calibration, optional
        The scale from a calibration image (:func:`grainplug.calibrate_image`, or
        ``grainplug calibrate``), taken along the tube's axis; instead of ``mm_per_px``.
        :func:`grainplug.analyze` also takes the path of a ``calibration.json``.
    background : Background, optional
        A light calibration: the tube empty or full, nothing moving, with the movie's
        camera and lamp (:func:`grainplug.read_background`); the diagram is divided by
        its light along the tube. :func:`grainplug.analyze` also takes the path of the
        picture or movie.
    packed : Background, optional
        The tube packed with still grains at ``packed_compactness``, with the same camera and
        lamp (read as ``background`` is): with ``background`` the tube *empty*, the grains'
        compactness is read along the tube from the light they let through
        (:mod:`grainplug.measures.compactness`).
    packed_compactness : float
        The packed reference's compactness (0.60: glass beads poured and settled).
    grain_density_kg_m3 : float
        The grains' material density (2500: glass beads, as the paper's), for their mass flow rate
        (:mod:`grainplug.measures.mass_flow`).
    start_frame, end_frame : int, optional
        Analyse frames ``start_frame`` (included) to ``end_frame`` (excluded) only, e.g. to
        leave out the start-up transient; counted from 0.
    start_s, end_s : float, optional
        The same window in seconds from the first frame (instead of frames; one of each pair).
        Frame times in the result stay those of the movie.
    roi : (x0, y0, x1, y1), optional
        Analyse only this rectangle of each frame (pixels, ``x1``/``y1`` excluded): the tube is
        looked for inside it. The way to choose one tube when a frame holds several. Positions
        along the tube then start at the rectangle's edge.
    mask_mm : sequence of (from_mm, to_mm)
        Stretches of the tube that hide its contents (a clamp, a label, a fitting), in mm from
        the upstream end of the view: blind stretches, as those found by themselves (where
        nothing changes over the record). A plug touching one is cut there (its length is not
        used, its other edge is); a bubble across one is not measured.

    Examples
    --------
    >>> AnalysisParams(fps=1000, mm_per_px=0.1875).replace(min_plug_mm=4.0).min_plug_mm
    4.0
    """

    fps: float | None = None
    mm_per_px: float | None = None
    tube_diameter_mm: float = 3.0
    tube_outer_diameter_mm: float | None = None
    glass_index: float = 1.47
    flow_direction: str | None = None
    min_plug_mm: float = 3.0
    min_gap_mm: float = 0.6
    sample_frames: int = 32
    glob: str | None = None
    allow_truncated: bool = False
    calibration: Calibration | None = None
    background: Background | None = None
    packed: Background | None = None
    packed_compactness: float = 0.60
    grain_density_kg_m3: float = 2500.0
    start_frame: int | None = None
    end_frame: int | None = None
    start_s: float | None = None
    end_s: float | None = None
    roi: tuple[int, int, int, int] | None = None
    mask_mm: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        def check(ok: bool, param: str, message: str) -> None:
            if not ok:
                raise ParameterError(message, param=param)

        for name, rng in RANGES.items():
            value = as_number(getattr(self, name))
            check(value is None or rng.holds(value), name, rng.message(value))
            if value is not None and rng.integer:
                value = int(value)  # 32.0 is 32 frames
            object.__setattr__(self, name, value)
        check(self.tube_outer_diameter_mm is None or self.tube_outer_diameter_mm > self.tube_diameter_mm * 1.05,
              "tube_outer_diameter_mm", f"must exceed the inner diameter ({self.tube_diameter_mm:g} mm) by at least "
              f"5 %, got {self.tube_outer_diameter_mm}")
        for name in ("start_frame", "end_frame"):
            value = as_number(getattr(self, name))
            if isinstance(value, float) and math.isfinite(value) and value == int(value):
                value = int(value)  # 5.0 is frame 5
            check(value is None or (isinstance(value, numbers.Integral) and not isinstance(value, bool)
                                    and 0 <= value <= 10**9), name, f"must be a frame number, 0 or more, got {value!r}")
            object.__setattr__(self, name, value)
        for name in ("start_s", "end_s"):
            value = as_number(getattr(self, name))
            check(value is None or (isinstance(value, numbers.Real) and not isinstance(value, bool)
                                    and math.isfinite(value) and 0 <= value <= 1e7),
                  name, f"must be a time in seconds, 0 or more, got {value!r}")
            object.__setattr__(self, name, value)
        check(self.start_frame is None or self.start_s is None, "start_frame", "give the start in frames or in "
              "seconds, not both")
        check(self.end_frame is None or self.end_s is None, "end_frame", "give the end in frames or in seconds, "
              "not both")
        check(self.flow_direction is None or self.flow_direction in FLOW_DIRECTIONS, "flow_direction",
              f"must be one of {', '.join(FLOW_DIRECTIONS)}, got {self.flow_direction!r}")
        check(self.calibration is None or hasattr(self.calibration, "mm_per_px_along"), "calibration",
              f"must be a Calibration (gp.load_calibration(path), or the path itself to gp.analyze), got a "
              f"{type(self.calibration).__name__}")
        check(self.background is None or hasattr(self.background, "image"), "background",
              f"must be a Background (gp.read_background(path), or the path itself to gp.analyze), got a "
              f"{type(self.background).__name__}")
        check(self.packed is None or hasattr(self.packed, "image"), "packed",
              f"must be a Background (gp.read_background(path), or the path itself to gp.analyze), got a "
              f"{type(self.packed).__name__}")
        check(self.packed is None or self.background is not None, "packed",
              "needs the empty tube's picture too (background=, --background): the compactness is read between "
              "the two")
        check(self.calibration is None or self.mm_per_px is None, "calibration",
              "give either a calibration or mm_per_px (the scale), not both")
        if self.roi is not None:
            r = self.roi
            try:  # a tuple, a list or an array of four whole numbers (0.0 is pixel 0)
                r = tuple(as_number(v) for v in r)  # type: ignore[union-attr]
            except TypeError:
                pass
            whole = (isinstance(r, tuple) and len(r) == 4
                     and all(isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)
                             and float(v) == int(v) for v in r))
            check(whole, "roi", f"must be four whole pixel numbers (x0, y0, x1, y1), got {self.roi!r}")
            r = tuple(int(v) for v in r)
            check(0 <= r[0] < r[2] and 0 <= r[1] < r[3], "roi",
                  f"must have 0 <= x0 < x1 and 0 <= y0 < y1 (x1, y1 excluded), got {r}")
            object.__setattr__(self, "roi", r)
        object.__setattr__(self, "mask_mm", _stretches(self.mask_mm))

    def as_record(self) -> dict[str, object]:
        """The parameters as plain data, for provenance and run keys: a background is recorded by its
        identity (name, size, SHA-256), not its pixels."""
        d = dataclasses.asdict(dataclasses.replace(self, background=None, packed=None))
        d["background"] = self.background.describe() if self.background is not None else None
        d["packed"] = self.packed.describe() if self.packed is not None else None
        return d

    def replace(self, **changes: object) -> AnalysisParams:
        """A copy with some fields changed (checked like the original)."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            names = ", ".join(f.name for f in dataclasses.fields(self))
            raise ParameterError(f"unknown parameter {', '.join(sorted(unknown))}; the parameters are {names}",
                                 param=sorted(unknown)[0])
        return dataclasses.replace(self, **changes)


def _stretches(value: object) -> tuple[tuple[float, float], ...]:
    """``mask_mm`` as a sorted tuple of ``(from_mm, to_mm)`` pairs of finite numbers, ``from < to``."""
    if value is None:
        return ()
    if (isinstance(value, (tuple, list)) and len(value) == 2
            and all(isinstance(as_number(v), numbers.Real) for v in value)):
        value = [value]  # one stretch, not nested
    try:
        pairs = [tuple(as_number(v) for v in pair) for pair in value]  # type: ignore[union-attr]
    except TypeError:
        pairs = []
        value = [value]
    out = []
    for pair in pairs or ([] if not value else [None]):
        ok = (isinstance(pair, tuple) and len(pair) == 2
              and all(isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v) for v in pair)
              and pair[0] < pair[1] and pair[0] >= 0)
        if not ok:
            raise ParameterError(f"must be stretches (from_mm, to_mm) with 0 <= from_mm < to_mm, in mm from the "
                                 f"upstream end of the view, got {value!r}", param="mask_mm")
        out.append((float(pair[0]), float(pair[1])))
    return tuple(sorted(out))


#: library keywords whose command-line option has another name (``start_s=`` is ``--start``)
OPTION_ALIASES = {"start_frame": "start", "start_s": "start", "end_frame": "end", "end_s": "end", "out_dir": "out",
                  "base_pressure_pa": "base_pressure"}


def with_options(text: str) -> str:
    """``text`` with each analysis keyword it names (``tube_outer_diameter_mm=``) followed by its command-line
    option (``tube_outer_diameter_mm= (--tube-outer-diameter-mm)``): saved results keep the library's words,
    and a reader who ran the command line finds the flag beside them."""
    names = {f.name for f in dataclasses.fields(AnalysisParams)} | set(OPTION_ALIASES)

    def one(m: re.Match[str]) -> str:
        name = m.group(1)
        if name not in names:
            return m.group(0)
        return f"{m.group(0)} (--{OPTION_ALIASES.get(name, name).replace('_', '-')})"

    return re.sub(r"(?<![\w.\-])([a-z][a-z0-9_]*)=(?![=\w\"'(])", one, text)
