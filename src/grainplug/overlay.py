"""An overlay video of an analysis: the raw frames around the tube with what was detected on them.

Notes
-----
Each frame of the analysis is cropped around the tube (six diameters either side, as
the annotated figure), shown with the tube's inner walls (orange), every plug's upper
(vermillion) and lower (blue) edge with its track number, a scale bar and the time stamp. ``slowdown``
plays the movie that many times slower: the video keeps the movie's timing, slowed, whichever frames it keeps.
``every`` keeps one frame in that many, each shown for the time of the frames it stands for; without a
``slowdown``, it is chosen for the frames kept to play at :data:`DEFAULT_MAX_FPS` frames per second (real time
when they come slower), so that ``every=4`` gives a video four times shorter at a player's usual rate, not one as
long at a quarter of it. Frames are read one at a time, so memory does not grow with the movie.

The container follows the file name:

- ``.mp4``: H.264 (PyAV's libx264, ``yuv420p``, CRF 18), which plays everywhere and is what
  labs put in supplementary material. It needs PyAV (``pip install "grainplug[video]"``),
  whose wheels bundle the GPL encoder x264, so it is not in the default install;
- ``.webm``: VP8 through OpenCV's FFmpeg (in the default install), which plays in every
  current browser (Chromium, Firefox, Safari 14.1+). VP9 would be smaller but is encoded
  ten times slower by OpenCV's default settings.

The default is ``overlay.mp4`` where PyAV is installed and ``overlay.webm`` otherwise.

The drawing (:func:`draw_frame`) takes arrays only; :func:`write_overlay` opens the
movie and writes the file atomically.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import GrainplugError, ParameterError
from .params import runs_backwards
from .plotting import palette
from .plotting.figures import crop_box
from .plotting.palette import bgr

if TYPE_CHECKING:
    from .result import AnalysisResult

#: colours (BGR for OpenCV) of :mod:`grainplug.plotting.palette`: upper edges, lower edges, walls; text
RED, BLUE, ORANGE, WHITE = bgr(palette.UPPER), bgr(palette.LOWER), bgr(palette.WALL), (255, 255, 255)
#: default output frame rate when no slow-down is given: at most this many frames per second
DEFAULT_MAX_FPS = 30.0


def analysed_region(res: AnalysisResult, frame: np.ndarray) -> np.ndarray:
    """The part of a movie frame the analysis saw (its ``roi``, or the whole frame)."""
    roi = res.params.roi
    if roi is None:
        return np.asarray(frame)
    x0, y0, x1, y1 = roi
    return np.asarray(frame)[y0:y1, x0:x1]


def _to_bgr8(frame: np.ndarray, top: float) -> np.ndarray:
    f = np.asarray(frame)
    g = f.astype(np.float32) * (255.0 / top) if f.dtype != np.uint8 else f
    g = np.clip(g, 0, 255).astype(np.uint8)
    if g.ndim == 2:
        return np.repeat(g[:, :, None], 3, axis=2)
    return np.ascontiguousarray(g[:, :, :3][:, :, ::-1])


def sensor_top(res: AnalysisResult) -> float:
    """The top value of the analysed movie's samples (its bit depth's; 255 when unknown): what
    :func:`draw_frame` scales to 8 bits."""
    return float((1 << int(res.info.bit_depth)) - 1) if res.info.bit_depth else 255.0


def draw_frame(res: AnalysisResult, frame: np.ndarray, k: int, *, top_value: float = 255.0) -> np.ndarray:
    """Frame ``k`` of the analysis as a BGR uint8 image cropped around the tube, with the detection on it."""
    import cv2

    tube = res.tube
    vertical = tube.orientation == "vertical"
    img = _to_bgr8(frame, top_value)
    if not vertical:  # draw in the tube's frame of reference (axis down the rows), turn back at the end
        img = np.ascontiguousarray(img.transpose(1, 0, 2))
    lo, hi = crop_box(res)
    img = np.ascontiguousarray(img[:, lo:hi])
    h = img.shape[0]
    rows = np.arange(h, dtype=float)
    half = 0.5 * tube.inner_diameter_px / math.cos(math.radians(tube.tilt_deg))
    axis = tube.axis_x(rows) - lo
    for side in (-1, 1):
        pts = np.stack([axis + side * half, rows], axis=1).round().astype(np.int32)
        cv2.polylines(img, [np.ascontiguousarray(pts[::4]).reshape(-1, 1, 2)], False, ORANGE, 1, cv2.LINE_AA)
    cos_t = math.cos(math.radians(tube.tilt_deg))
    reverse = runs_backwards(res.flow_direction)
    sel = np.flatnonzero(res.runs.frame == k)
    labels = []  # (track number, row along the tube, column beside it): written after turning back
    for i in sel:
        tid = int(res.links.run_track[i])
        for pos, colour in ((res.runs.top_mm[i], RED), (res.runs.bottom_mm[i], BLUE)):
            if not np.isfinite(pos):
                continue
            row = pos / res.mm_per_px * cos_t - 0.5
            if reverse:
                row = h - 1 - row
            xc = float(tube.axis_x(np.array([row]))[0]) - lo
            y = int(round(row))
            cv2.line(img, (int(round(xc - half - 3)), y), (int(round(xc + half + 3)), y), colour, 2, cv2.LINE_AA)
            if colour == RED:
                labels.append((tid, y, int(round(xc + half + 6))))
    if not vertical:  # back to the movie's orientation: the text is written upright, in the final image
        img = np.ascontiguousarray(img.transpose(1, 0, 2))
    font, small = cv2.FONT_HERSHEY_SIMPLEX, 0.4
    for tid, along, beside in labels:
        at = (beside, along + 4) if vertical else (along - 4, beside + 10)
        cv2.putText(img, str(tid), at, font, small, RED, 1, cv2.LINE_AA)
    # scale bar along the tube (10 mm, or 5 / 2 / 1 mm when the view is short) and time stamp, on dark bands
    bar_mm = next((b for b in (10.0, 5.0, 2.0, 1.0) if b / res.mm_per_px < 0.4 * h), 1.0)
    bar_px = int(round(bar_mm / res.mm_per_px))
    rows, cols = img.shape[:2]
    if vertical:  # a vertical bar at the bottom left, its length written beside it
        cv2.rectangle(img, (0, rows - bar_px - 14), (min(cols - 1, 60), rows - 1), (0, 0, 0), -1)
        cv2.line(img, (6, rows - 8), (6, rows - 8 - bar_px), WHITE, 2)
        cv2.putText(img, f"{bar_mm:g} mm", (11, rows - 10), font, 0.35, WHITE, 1, cv2.LINE_AA)
    else:  # a horizontal bar at the bottom left, its length written above it
        cv2.rectangle(img, (0, rows - 24), (min(cols - 1, max(bar_px + 12, 50)), rows - 1), (0, 0, 0), -1)
        cv2.line(img, (6, rows - 6), (6 + bar_px, rows - 6), WHITE, 2)
        cv2.putText(img, f"{bar_mm:g} mm", (6, rows - 12), font, 0.35, WHITE, 1, cv2.LINE_AA)
    t = float(res.diagram.time_s[k])
    # top left; in a band too short for both boxes above each other, top right, clear of the scale bar's
    x0 = max(cols - 111, 0) if rows < 44 and not vertical else 0
    cv2.rectangle(img, (x0, 0), (min(cols - 1, x0 + 110), 16), (0, 0, 0), -1)
    cv2.putText(img, f"t = {t:.4f} s", (x0 + 3, 12), font, small, WHITE, 1, cv2.LINE_AA)
    return img


def _refuse_another_movie(recorded: dict, path: str) -> None:
    """Refuse a movie that is not the one analysed: its size or sampled content differ from those the
    analysis recorded (:func:`grainplug.provenance.fingerprint`), so the edges would be drawn on other frames.
    A movie gone is left to the reader's own message."""
    from .provenance import fingerprint

    if not recorded.get("sha256_sampled") or not Path(path).exists():
        return
    try:
        now = fingerprint(path)
    except OSError:
        return
    if now.get("sha256_sampled") != recorded.get("sha256_sampled") or now.get("bytes") != recorded.get("bytes"):
        raise GrainplugError(f"the movie {path} is not the one analysed (now {now.get('bytes'):,} bytes, "
                             f"{recorded.get('bytes'):,} then, and other content): its edges would be drawn on "
                             "other frames — analyse it again (grainplug analyze ... --overwrite), or put the "
                             "analysed movie back")


def write_overlay(folder: str | Path, out: str | Path | None = None, *, slowdown: float | None = None,
                  every: int = 1) -> Path:
    """Write the overlay video of the analysis saved in ``folder``; returns its path.

    Parameters
    ----------
    folder : path
        An analysis (``grainplug analyze --out``); its movie must still be where it was analysed.
    out : path, optional
        The video file: ``.mp4`` (H.264, needs PyAV) or ``.webm`` (VP8); default
        ``folder/overlay.mp4`` where PyAV is installed, else ``folder/overlay.webm``.
    slowdown : float, optional
        Play this many times slower than real time (default: slow enough for the frames kept to play at
        most :data:`DEFAULT_MAX_FPS` frames per second, i.e. real time for slow cameras). The video's rate is
        ``fps / slowdown / every``.
    every : int
        Keep one frame in ``every`` (a shorter video of a long record); with the default slow-down, the video
        is ``every`` times shorter.
    """
    from ._atomic import atomic_file, refuse_overwriting_inputs
    from .readers import open_movie, pyav_available
    from .result import load_result

    res = load_result(folder)
    if every < 1:
        raise ParameterError("every must be at least 1", param="every")
    path = res.input.get("path") if isinstance(res.input, dict) else None
    if not path:
        raise GrainplugError("the analysis was made from frames in memory: there is no movie to draw on")
    fps = float(res.info.fps)
    slow = max(1.0, fps / every / DEFAULT_MAX_FPS) if slowdown is None else float(slowdown)  # of the frames kept
    if not (math.isfinite(slow) and slow > 0):
        raise ParameterError("the slow-down must be a positive number", param="slowdown")
    out_fps = fps / slow / every
    target = Path(out) if out is not None else Path(folder) / ("overlay.mp4" if pyav_available() else "overlay.webm")
    kind = target.suffix.lower()
    if kind not in (".mp4", ".webm"):
        raise ParameterError(f"the overlay is an MP4 or a WebM file: give a name ending in .mp4 or .webm, not "
                             f"{target.name}", param="out")
    if kind == ".mp4" and not pyav_available():
        raise ParameterError('an MP4 (H.264) overlay needs PyAV: pip install "grainplug[video]", or give a name '
                             "ending in .webm", param="out")
    refuse_overwriting_inputs([target], [path])  # an overlay named as the movie would replace it
    _refuse_another_movie(res.input, path)
    top = sensor_top(res)
    p = res.params
    try:
        movie = open_movie(path, fps=p.fps, glob=p.glob, allow_truncated=True)
    except (GrainplugError, OSError) as exc:
        raise GrainplugError(f"cannot open the movie {path} ({exc}) — the overlay draws on the analysed movie, "
                             "put it back where it was") from None
    with movie, atomic_file(target, inputs=[path]) as tmp:
        from .readers.window import window_start

        offset = window_start(movie, p)
        n = res.diagram.n_frames
        frames = (draw_frame(res, analysed_region(res, frame), k, top_value=top)
                  for k, frame in zip(range(0, n, every), movie.frames(offset, offset + n, every), strict=False))
        (_write_h264 if kind == ".mp4" else _write_vp8)(tmp, frames, out_fps)
    return target


def _write_h264(path: Path, frames: Iterator[np.ndarray], fps: float) -> None:
    """BGR frames as H.264 in an MP4 file (PyAV's libx264, ``yuv420p``, CRF 18)."""
    from fractions import Fraction

    import av

    container = av.open(str(path), mode="w", format="mp4")
    try:
        stream = None
        for img in frames:
            h, w = img.shape[:2]
            img = np.ascontiguousarray(img[: h - h % 2, : w - w % 2])  # yuv420p: even sizes
            if stream is None:
                stream = container.add_stream("libx264", rate=Fraction(fps).limit_denominator(1000))
                stream.width, stream.height = img.shape[1], img.shape[0]
                stream.pix_fmt = "yuv420p"
                stream.options = {"crf": "18", "preset": "veryfast"}
            for packet in stream.encode(av.VideoFrame.from_ndarray(img, format="bgr24")):
                container.mux(packet)
        if stream is not None:
            for packet in stream.encode():
                container.mux(packet)
    finally:
        container.close()


def _write_vp8(path: Path, frames: Iterator[np.ndarray], fps: float) -> None:
    """BGR frames as VP8 in a WebM file, through OpenCV's FFmpeg (about 1 bit per pixel per frame)."""
    import cv2

    from ._system import quiet_stderr

    writer = None
    try:
        for img in frames:
            h, w = img.shape[:2]
            img = np.ascontiguousarray(img[: h - h % 2, : w - w % 2])
            if writer is None:
                with quiet_stderr():  # OpenCV prints a harmless note about WebM's codec tags
                    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"VP80"), fps,
                                             (img.shape[1], img.shape[0]))
                if not writer.isOpened():
                    raise GrainplugError("OpenCV cannot write WebM (VP8) video here — install PyAV and write an "
                                         'MP4: pip install "grainplug[video]"')
            writer.write(img)
    finally:
        if writer is not None:
            writer.release()
