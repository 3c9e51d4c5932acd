"""Light calibration: flat-fielding the diagram with a picture of the tube empty (or full).

The paper took "light calibrations" before each test. A frame (or a short movie) of
the tube with nothing moving in it — empty, or full of grains — records how the
light varies along the tube: the lamp's gradient, vignetting, dust and scratches on
the glass. Dividing the diagram by that profile removes them before the plugs are
looked for (:func:`flat_field`). Without one, grainplug learns a smooth light
profile from the movie itself (:func:`grainplug.diagram.normalize`), which cannot
follow a sharp spot.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..band import Band

#: a background darker than this share of its median along the band is not lit there
DARK_SHARE = 0.1


@dataclass(frozen=True)
class Background:
    """A picture of the tube with nothing moving in it, for flat-fielding.

    Attributes
    ----------
    image : ndarray
        Grey image (float32, the movie's frame size), the mean of the frames given.
    identity : dict
        Name, size and SHA-256 of the file it came from.
    n_frames : int
        Frames averaged.
    """

    image: np.ndarray = field(repr=False)
    identity: dict[str, object] = field(default_factory=dict)
    n_frames: int = 1

    def describe(self) -> dict[str, object]:
        """What to record in a result's provenance (not the pixels)."""
        return {**self.identity, "n_frames": self.n_frames, "shape": list(self.image.shape)}


def grey_background(frames: np.ndarray | list[np.ndarray], *, identity: dict[str, object] | None = None) -> Background:
    """A :class:`Background` from frames (grey or colour): their mean, in grey."""
    stack = [np.asarray(f, dtype=np.float64) for f in (frames if isinstance(frames, list) else list(frames))]
    if not stack:
        raise ValueError("no frames for the background")
    mean = np.mean(stack, axis=0)
    if mean.ndim == 3:
        mean = mean[..., :3].mean(axis=2)
    return Background(mean.astype(np.float32), dict(identity or {}), len(stack))


#: a pixel moves when its grey level varies over the frames by more than this many times the noise (the median
#: pixel's variation), and by more than this share of the picture's contrast
MOVING_OVER_NOISE, MOVING_CONTRAST = 8.0, 0.03
#: a background moves when more than this share of its pixels do (a plug-flow movie given as the background)
MOVING_SHARE = 0.01


def moving_share(frames: np.ndarray | list[np.ndarray]) -> float:
    """The share of pixels whose grey level varies over ``frames`` far above the noise (0 for fewer than 3).

    Each frame is first divided by its median, so that a lamp's flicker does not count as motion; a pixel
    moves when its standard deviation over the frames exceeds both :data:`MOVING_OVER_NOISE` times the median
    pixel's (the noise: most of a background picture is still) and :data:`MOVING_CONTRAST` of the picture's
    contrast (a noiseless picture).
    """
    stack = np.asarray([np.asarray(f, dtype=np.float32) for f in frames])
    if len(stack) < 3:
        return 0.0
    if stack.ndim == 4:
        stack = stack[..., :3].mean(axis=3)
    med = np.median(stack.reshape(len(stack), -1), axis=1)
    stack = stack / np.where(med > 0, med, 1.0)[:, None, None]
    sd = stack.std(axis=0)
    mean = stack.mean(axis=0)
    contrast = float(np.percentile(mean, 99) - np.percentile(mean, 1))
    threshold = max(MOVING_OVER_NOISE * float(np.median(sd)), MOVING_CONTRAST * contrast, 1e-6)
    return float(np.mean(sd > threshold))


def flat_field(values: np.ndarray, band: Band, background: Background) -> tuple[np.ndarray, list[str]]:
    """The diagram divided by the background's light along the tube.

    Parameters
    ----------
    values : ndarray, (n_frames, n_positions)
        The raw diagram, sampled with ``band``.
    band : Band
        Where the diagram was sampled.
    background : Background
        The tube with nothing moving in it, same frame size as the movie.

    Returns
    -------
    values : ndarray
        ``values / (B(s) / median B)``, float32: the light along the tube made flat
        (where the background is darker than 10 % of its median, nothing is lit to
        correct and the gain is held at 0.1).
    warnings : list of str
        What is doubtful.

    Notes
    -----
    Flat-fielding by the transmitted light: a material of transmittance ``tau`` at
    position ``s`` under light ``B(s)`` shows ``tau B(s)``, so ``D / B`` depends on
    the material alone. An empty tube gives the bubbles' light and a full one the
    plugs'; both have the same shape along the tube.
    """
    ref = band.profile(background.image).astype(np.float64)
    med = float(np.median(ref))
    warnings: list[str] = []
    if not med > 0:
        return np.asarray(values, dtype=np.float32), ["the background is black along the tube: it was not used — "
                                                      "take it with the lamp on and nothing moving in the tube"]
    gain = ref / med
    dark = gain < DARK_SHARE
    if dark.mean() > 0.01:
        warnings.append(f"the background is dark over {100 * dark.mean():.0f} % of the tube: those parts are not lit "
                        "and were not corrected — was it taken with the lamp on, the camera and tube unmoved?")
    gain = np.maximum(gain, DARK_SHARE).astype(np.float32)
    return (np.asarray(values, dtype=np.float32) / gain[None, :]).astype(np.float32), warnings
