"""Render synthetic movies of plug flow in a back-lit (or front-lit) glass tube."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from ..errors import ParameterError
from ..params import FLOW_DIRECTIONS
from .kinematics import REGIMES, PlugTrain, build_train, displacement_mm

MERGE_FREQUENCY_HZ = 1.0


#: bytes the renderer holds per pixel of a frame (coordinates, shading and the frame, in float64)
RENDER_BYTES_PER_PX = 64
#: the largest frame rendered, pixels
MAX_FRAME_PX = 2**28
#: the most plugs a movie's train may hold (they are drawn one by one)
MAX_PLUGS = 1e6


@dataclass(frozen=True)
class SynthConfig:
    """Everything that defines a synthetic plug-flow movie.

    Lengths in mm, times in s, celerities in m/s (positive downstream), grey
    levels on the 8-bit scale (scaled by 257 for 16-bit output).

    Attributes
    ----------
    width_px, height_px : int
        Frame size of the canonical (flow-downward) view; swapped for a
        horizontal tube (``flow_direction`` left/right).
    n_frames, fps : int, float
        Length and frame rate of the movie.
    mm_per_px : float
        Scale of the image.
    tube_diameter_mm, wall_mm : float
        Inner diameter and wall thickness of the glass tube.
    tube_offset_px : float
        Shift of the tube axis from the frame centre, across the tube.
    tilt_deg : float
        Tilt of the tube axis in the image (|tilt| <= 5).
    flow_direction : {"down", "up", "left", "right"}
        Direction of the grain flow in the image.
    polarity : {"dark", "bright"}
        ``dark``: back-lit, dark plugs on a bright field. ``bright``: bright
        plugs on a dark field.
    rgb : bool
        Write RGB frames (tinted by ``tint``) rather than grey.
    tint : tuple of float
        RGB gains of the light.
    bit_depth : {8, 16}
        Sample depth of the frames.
    regime : {"propagative", "oscillating", "stick-slip", "none"}
        Motion of the plug train; ``none`` renders a movie with no plugs.
    no_plug_fill : {"empty", "compact"}
        With ``regime="none"``: an empty tube (sparse falling grains) or a
        compact column of grains sliding at ``celerity_m_s``.
    celerity_m_s : float
        Mean celerity of the plugs (drift celerity), positive downstream.
    frequency_hz, amplitude_mm, stick_fraction : float
        Oscillation frequency, sinusoid amplitude (oscillating) and the stuck
        part of each period (stick-slip).
    plug_length_mm, plug_length_sd_mm, bubble_length_mm, bubble_length_sd_mm : float
        Mean and spread of plug and bubble lengths.
    edge_roughness_mm : float
        Amplitude of the irregularity of plug interfaces across the tube.
    merge_split : bool
        Make every third plug join the plug above it and split again.
    falling_grains_per_mm : float
        Density of grains falling through the bubbles (per mm of bubble).
    falling_speed_m_s : float
        Their speed (free fall, ~0.8 m/s in the paper).
    noise_sigma : float
        Gaussian sensor noise (8-bit grey levels).
    flicker : float
        Frame-to-frame light fluctuation, uniform in ``[-flicker, +flicker]``.
    gradient : float
        Relative fall of the illumination from the top to the bottom of the view.
    seed : int
        Seed of the random generator: same seed, same bytes.
    extra : dict
        Notes of one's own, written into ``truth.json`` with the rest; the renderer does
        not read them.
    """

    width_px: int = 128
    height_px: int = 640
    n_frames: int = 300
    fps: float = 250.0
    mm_per_px: float = 0.185
    tube_diameter_mm: float = 3.0
    wall_mm: float = 1.0
    tube_offset_px: float = 0.0
    tilt_deg: float = 0.0
    flow_direction: str = "down"
    polarity: str = "dark"
    rgb: bool = True
    tint: tuple[float, float, float] = (1.0, 0.93, 0.8)
    bit_depth: int = 8
    regime: str = "propagative"
    no_plug_fill: str = "empty"
    celerity_m_s: float = -0.05
    frequency_hz: float = 7.0
    amplitude_mm: float = 1.5
    stick_fraction: float = 0.5
    plug_length_mm: float = 30.0
    plug_length_sd_mm: float = 2.0
    bubble_length_mm: float = 25.0
    bubble_length_sd_mm: float = 4.0
    edge_roughness_mm: float = 0.3
    merge_split: bool = False
    falling_grains_per_mm: float = 0.4
    falling_speed_m_s: float = 0.8
    noise_sigma: float = 3.0
    flicker: float = 0.0
    gradient: float = 0.0
    seed: int = 0
    extra: dict[str, object] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        checks = [
            (self.width_px >= 16 and self.height_px >= 16, "frame size must be at least 16 px"),
            (self.n_frames >= 1, "n_frames must be >= 1"),
            (self.fps > 0, "fps must be positive"),
            (self.mm_per_px > 0, "mm_per_px must be positive"),
            (self.tube_diameter_mm > 0 and self.wall_mm >= 0, "tube sizes must be positive"),
            (abs(self.tilt_deg) <= 5.0, "tilt_deg must be within +-5 degrees"),
            (self.flow_direction in FLOW_DIRECTIONS, f"flow_direction must be one of {FLOW_DIRECTIONS}"),
            (self.polarity in ("dark", "bright"), "polarity must be 'dark' or 'bright'"),
            (self.bit_depth in (8, 16), "bit_depth must be 8 or 16"),
            (self.regime in REGIMES, f"regime must be one of {REGIMES}"),
            (self.no_plug_fill in ("empty", "compact"), "no_plug_fill must be 'empty' or 'compact'"),
            (self.frequency_hz > 0, "frequency_hz must be positive"),
            (0 <= self.stick_fraction < 1, "stick_fraction must be in [0, 1)"),
            (self.plug_length_mm > 0 and self.bubble_length_mm > 0, "plug and bubble lengths must be positive"),
            (self.noise_sigma >= 0 and 0 <= self.flicker < 0.5 and 0 <= self.gradient < 0.9,
             "noise_sigma >= 0, 0 <= flicker < 0.5, 0 <= gradient < 0.9"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ParameterError(msg)
        self._check_sizes()
        outer_px = (self.tube_diameter_mm + 2 * self.wall_mm) / self.mm_per_px
        if outer_px + 2 * abs(self.tube_offset_px) + 4 > self.width_px:
            raise ParameterError(
                f"the tube ({outer_px:.0f} px wide) does not fit in {self.width_px} px — "
                "widen the frame or coarsen mm_per_px"
            )

    def _check_sizes(self) -> None:
        """Refuse, before anything is allocated, a seed numpy cannot take, a frame too large to render in the
        memory there is, and plugs so fast or so short that their train could not be drawn."""
        from .._system import free_memory_bytes

        if not 0 <= self.seed < 2**63:
            raise ParameterError(f"must be a whole number from 0 to 2**63 - 1, got {self.seed}", param="seed")
        pixels = float(self.width_px) * float(self.height_px)
        need = pixels * RENDER_BYTES_PER_PX
        free = free_memory_bytes()
        if pixels > MAX_FRAME_PX or need > free / 2:
            big = "width_px" if self.width_px >= self.height_px else "height_px"
            raise ParameterError(
                f"a {self.width_px} x {self.height_px} px frame needs about {need / 2**30:.3g} GiB to render "
                f"({free / 2**30:.3g} GiB free; at most {MAX_FRAME_PX / 1e6:.0f} million pixels a frame) — "
                "give a smaller width_px= and height_px=", param=big)
        duration = self.n_frames / self.fps
        travel = abs(self.celerity_m_s) * 1000 * duration + 2 * abs(self.amplitude_mm)
        step = max(0.25 * self.plug_length_mm, 1.0) + 0.3 * self.bubble_length_mm
        n_plugs = (2 * travel + self.height_px * self.mm_per_px * 1.01 + 3 * self.plug_length_mm) / step
        if not np.isfinite(n_plugs) or n_plugs > MAX_PLUGS:
            fast = abs(self.celerity_m_s) * 1000 * duration >= abs(self.amplitude_mm)
            what = (f"plugs at {self.celerity_m_s:g} m/s travel {travel / 1000:.3g} m in the movie's {duration:.3g} s"
                    if fast else f"plugs that swing {self.amplitude_mm:g} mm")
            raise ParameterError(f"{what}: about {n_plugs:.3g} plugs to draw (at most {MAX_PLUGS:.0e}) — give a "
                                 "celerity_m_s= of a few m/s at most, or fewer n_frames=",
                                 param="celerity_m_s" if fast else "amplitude_mm")

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) of the written frames."""
        if self.flow_direction in ("left", "right"):
            return self.width_px, self.height_px
        return self.height_px, self.width_px

    @property
    def view_length_mm(self) -> float:
        """Length of tube axis inside the view, in mm."""
        return self.height_px / np.cos(np.radians(self.tilt_deg)) * self.mm_per_px

    def as_dict(self) -> dict[str, object]:
        d = dataclasses.asdict(self)
        d["tint"] = list(self.tint)
        return d


def merge_offset_mm(train: PlugTrain, t_s: float) -> np.ndarray:
    """Upstream excursion of each plug (merging/splitting), mm (<= 0)."""
    if not np.any(train.merge_amplitude_mm):
        return np.zeros(len(train))
    s = np.sin(2 * np.pi * MERGE_FREQUENCY_HZ * t_s + train.merge_phase_rad)
    return -train.merge_amplitude_mm * np.clip(1.6 * s, 0.0, 1.0)


class Renderer:
    """Renders frames of a :class:`SynthConfig` one at a time, with their truth."""

    def __init__(self, config: SynthConfig) -> None:
        self.cfg = cfg = config
        self.rng = np.random.default_rng(cfg.seed)
        h, w = cfg.height_px, cfg.width_px
        alpha = np.radians(cfg.tilt_deg)
        self._alpha = alpha
        self.x_axis_top_px = (w - 1) / 2 + cfg.tube_offset_px - 0.5 * h * np.tan(alpha)
        self.R_in = cfg.tube_diameter_mm / 2
        self.R_out = self.R_in + cfg.wall_mm
        px = cfg.mm_per_px
        # band of columns holding the tube
        reach = (self.R_out + 3 * px) / np.cos(alpha) / px
        xs_axis = self.x_axis_top_px + (np.arange(h) + 0.5) * np.tan(alpha)
        x0 = int(max(0, np.floor(xs_axis.min() - reach)))
        x1 = int(min(w, np.ceil(xs_axis.max() + reach) + 1))
        self._cols = slice(x0, x1)
        yy, xx = np.mgrid[0:h, x0:x1].astype(float)
        dx = xx - self.x_axis_top_px
        self.s_mm = (dx * np.sin(alpha) + (yy + 0.5) * np.cos(alpha)) * px
        self.r_mm = (dx * np.cos(alpha) - (yy + 0.5) * np.sin(alpha)) * px
        self.row_s_mm = (np.arange(h) + 0.5) * px  # background gradient along the image
        # kinematics: the train spans every position plugs can reach during the movie
        duration = cfg.n_frames / cfg.fps
        travel = abs(cfg.celerity_m_s) * 1000 * duration + 2 * cfg.amplitude_mm + 10
        span = (-travel - cfg.plug_length_mm * 2, cfg.view_length_mm + travel + cfg.plug_length_mm)
        self.train = build_train(
            self.rng, span_mm=span, plug_length_mm=cfg.plug_length_mm,
            plug_length_sd_mm=cfg.plug_length_sd_mm, bubble_length_mm=cfg.bubble_length_mm,
            bubble_length_sd_mm=cfg.bubble_length_sd_mm, merge_split=cfg.merge_split,
        )
        self.phase = float(self.rng.uniform(0, 2 * np.pi))
        n = len(self.train)
        # interface roughness: a smooth random profile across the tube, per plug and edge
        r_grid = np.linspace(-self.R_in, self.R_in, 33)
        rough = ndimage.gaussian_filter1d(self.rng.normal(size=(n, 2, 33)), 4, axis=-1)
        rough -= rough.mean(axis=-1, keepdims=True)  # the mean interface is the nominal edge
        rough /= np.maximum(rough.std(axis=-1, keepdims=True), 1e-9)
        self._rough = rough * cfg.edge_roughness_mm
        self._rough_r = r_grid
        # grain texture in material coordinates (u along the train, r across)
        cell = max(px * 0.6, 0.08)
        u_lo, u_hi = span[0] - 60.0, span[1] + 60.0
        nu = int((u_hi - u_lo) / cell) + 2
        nr = int(2 * self.R_in / cell) + 3
        tex = ndimage.gaussian_filter(self.rng.normal(size=(nu, nr)), 0.8)
        self._tex = (tex / tex.std()).astype(np.float32)
        self._tex_u0, self._tex_cell = u_lo, cell
        self._tex_r0 = -self.R_in - cell
        # falling grains: a population cycling through the view
        cycle = cfg.view_length_mm + 20.0
        n_grains = int(cfg.falling_grains_per_mm * cycle * 1.0)
        self._grain_s0 = self.rng.uniform(-10, cycle - 10, n_grains)
        self._grain_r = self.rng.uniform(-0.85 * self.R_in, 0.85 * self.R_in, n_grains)
        self._grain_cycle = cycle
        self._flicker = 1 + self.rng.uniform(-cfg.flicker, cfg.flicker, cfg.n_frames)
        self._noise_seed = int(self.rng.integers(2**32))
        self._rough_idx = np.clip(
            np.round((self.r_mm + self.R_in) / (2 * self.R_in) * 32).astype(int), 0, 32
        )

    # -- truth ---------------------------------------------------------------
    def displacement_mm(self, t_s: float | np.ndarray) -> np.ndarray:
        cfg = self.cfg
        return displacement_mm(
            t_s, regime=cfg.regime, celerity_m_s=cfg.celerity_m_s, frequency_hz=cfg.frequency_hz,
            amplitude_mm=cfg.amplitude_mm, stick_fraction=cfg.stick_fraction, phase_rad=self.phase,
        )

    def plug_edges_mm(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """Mean upper and lower edge of every plug of the train in frame ``index`` (mm)."""
        t = index / self.cfg.fps
        shift = self.displacement_mm(t) + merge_offset_mm(self.train, t)
        return self.train.top0_mm + shift, self.train.bottom0_mm + shift

    # -- rendering -----------------------------------------------------------
    def _levels(self) -> dict[str, float]:
        if self.cfg.polarity == "dark":
            return {"bg": 215.0, "air": 0.93, "wall": 0.82, "plug": 0.30, "tex": 0.22,
                    "grain": -0.55, "line": -0.45}
        return {"bg": 28.0, "air": 1.25, "wall": 1.6, "plug": 6.8, "tex": 0.18,
                "grain": 2.5, "line": 1.8}

    def render_grey(self, index: int) -> np.ndarray:
        """Noise-free grey frame (float, 8-bit scale) in the canonical orientation."""
        cfg = self.cfg
        lv = self._levels()
        h, w = cfg.height_px, cfg.width_px
        t = index / cfg.fps
        px = cfg.mm_per_px
        light = lv["bg"] * self._flicker[index] * (1 - cfg.gradient * self.row_s_mm / (h * px))
        frame = np.repeat(light[:, None], w, axis=1)
        s, r = self.s_mm, self.r_mm
        ar = np.abs(r)
        band_light = light[:, None]
        inside = np.clip((self.R_in - ar) / px + 0.5, 0, 1)
        wall = np.clip((self.R_out - ar) / px + 0.5, 0, 1) - inside
        lens = 1 - 0.12 * np.clip(r / self.R_in, -1, 1) ** 2
        line = np.exp(-(((ar - self.R_in) / (0.8 * px)) ** 2)) + 0.7 * np.exp(
            -(((ar - self.R_out) / (0.8 * px)) ** 2))
        # grain occupancy and texture
        cover = np.zeros_like(s)
        tex_val = np.zeros_like(s)
        if cfg.regime == "none":
            if cfg.no_plug_fill == "compact":
                cover[:] = 1.0
                u = s - self.displacement_mm(t)
                tex_val = self._texture(u, r)
        else:
            tops, bots = self.plug_edges_mm(index)
            shift = tops - self.train.top0_mm
            vis = np.nonzero((bots > -5) & (tops < cfg.view_length_mm + 5))[0]
            for i in vis:
                top_r = tops[i] + self._rough[i, 0][self._rough_idx]
                bot_r = bots[i] + self._rough[i, 1][self._rough_idx]
                c = np.clip((s - top_r) / px + 0.5, 0, 1) * np.clip((bot_r - s) / px + 0.5, 0, 1)
                new = np.maximum(cover, c)
                sel = c > 0
                if np.any(sel):
                    tv = self._texture(s[sel] - shift[i], r[sel])
                    tex_val[sel] = np.where(c[sel] >= cover[sel], tv, tex_val[sel])
                cover = new
        air_level = lv["air"] * lens
        plug_level = lv["plug"] * (1 + lv["tex"] * tex_val) * (1 - 0.25 * (r / self.R_in) ** 2)
        inner = air_level * (1 - cover) + plug_level * cover
        # sparse grains falling through the bubbles
        grains = self._falling_grains(t, cover)
        if grains is not None:
            inner = inner * (1 + lv["grain"] * grains) if lv["grain"] < 0 else inner + lv["grain"] * grains
        rel = inside * inner + wall * lv["wall"] + (1 - inside - wall)
        rel = rel * (1 + lv["line"] * np.clip(line, 0, 1)) if lv["line"] < 0 else rel + lv["line"] * line
        frame[:, self._cols] = band_light * rel
        return frame

    def _texture(self, u: np.ndarray, r: np.ndarray) -> np.ndarray:
        iu = np.clip(((u - self._tex_u0) / self._tex_cell).astype(np.int64), 0, self._tex.shape[0] - 1)
        ir = np.clip(((r - self._tex_r0) / self._tex_cell).astype(np.int64), 0, self._tex.shape[1] - 1)
        return self._tex[iu, ir]

    def _falling_grains(self, t: float, cover: np.ndarray) -> np.ndarray | None:
        if len(self._grain_s0) == 0:
            return None
        cfg = self.cfg
        pos = (self._grain_s0 + cfg.falling_speed_m_s * 1000 * t) % self._grain_cycle - 10
        keep = (pos > 0) & (pos < cfg.view_length_mm)
        if not np.any(keep):
            return None
        px = cfg.mm_per_px
        a = self._alpha
        # back to image coordinates (canonical view) of the band
        x = self.x_axis_top_px + (pos[keep] * np.sin(a) + self._grain_r[keep] * np.cos(a)) / px
        y = (pos[keep] * np.cos(a) - self._grain_r[keep] * np.sin(a)) / px - 0.5
        img = np.zeros_like(cover)
        xi = x - self._cols.start
        yi = np.floor(y).astype(int)
        xf = np.floor(xi).astype(int)
        fy, fx = y - yi, xi - xf
        for dy, wy in ((0, 1 - fy), (1, fy)):
            for dx, wx in ((0, 1 - fx), (1, fx)):
                yy, xx = yi + dy, xf + dx
                ok = (yy >= 0) & (yy < img.shape[0]) & (xx >= 0) & (xx < img.shape[1])
                np.add.at(img, (yy[ok], xx[ok]), (wy * wx)[ok])
        img = np.clip(img * 1.6, 0, 1)
        return img * (1 - cover)  # grains are only seen in the bubbles

    def frame(self, index: int) -> np.ndarray:
        """Final frame ``index``: oriented, tinted, noisy, quantised."""
        cfg = self.cfg
        grey = self.render_grey(index)
        noise_rng = np.random.default_rng([self._noise_seed, index])
        if cfg.rgb:
            img = grey[..., None] * np.asarray(cfg.tint, dtype=float)[None, None, :]
        else:
            img = grey
        if cfg.noise_sigma > 0:
            img = img + noise_rng.normal(0.0, cfg.noise_sigma, img.shape)
        img = _orient(img, cfg.flow_direction)
        if cfg.bit_depth == 16:
            return np.clip(np.rint(img * 257.0), 0, 65535).astype(np.uint16)
        return np.clip(np.rint(img), 0, 255).astype(np.uint8)

    def frames(self) -> Iterator[np.ndarray]:
        for i in range(self.cfg.n_frames):
            yield self.frame(i)


def _orient(img: np.ndarray, direction: str) -> np.ndarray:
    """Turn a canonical (flow downward) frame into the requested flow direction."""
    if direction == "down":
        return img
    if direction == "up":
        return img[::-1]
    if direction == "right":  # top of the canonical view goes to the left
        return np.ascontiguousarray(np.swapaxes(img, 0, 1))
    if direction == "left":
        return np.ascontiguousarray(np.swapaxes(img, 0, 1)[:, ::-1])
    raise ValueError(direction)
