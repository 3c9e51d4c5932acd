"""`analyze` on movies drawn by an independent, deliberately different renderer.

Not grainplug.synthetic: no glass walls, no lens shading, no moving grain texture
(grain noise is redrawn every frame), Gaussian optical blur, shot noise, a linear
illumination ramp across the frame, plugs as blurred bands. The analysis was not
developed on these movies; the accuracy targets are those of the analyze issue.
"""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from scipy import ndimage

from grainplug import AnalysisParams, analyze


def render(path, *, rng, n_frames=300, fps=250.0, h=720, w=160, mm_per_px=0.15, tube_px=20.0,
           celerity_m_s=-0.045, plug_mm=28.0, bubble_mm=22.0, dark_plugs=True, osc=None):
    """Write a TIFF stack and return (celerity_m_s, mean plug length of plugs seen whole, frequency)."""
    x0 = w * 0.37
    tops = np.arange(-400.0, h * mm_per_px + 400.0, plug_mm + bubble_mm)
    lengths = plug_mm * (1 + 0.06 * rng.standard_normal(len(tops)))
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    inside = np.abs(xx - x0) < tube_px / 2
    ramp = 1.0 - 0.3 * xx / w  # illumination falls across the frame, not along the tube
    s = (yy + 0.5) * mm_per_px
    seen = set()
    with tifffile.TiffWriter(path) as tif:
        for k in range(n_frames):
            t = k / fps
            shift = celerity_m_s * 1000 * t
            if osc:
                f, a = osc
                shift += a * np.sin(2 * np.pi * f * t)
            grains = np.zeros((h, w))
            view = h * mm_per_px
            for top, ln in zip(tops + shift, lengths, strict=True):
                if top >= 0 and top + ln <= view:
                    seen.add(round(float(ln), 9))
                grains = np.maximum(grains, ((s >= top) & (s < top + ln)).astype(float))
            grains *= inside
            texture = 1 + 0.25 * rng.standard_normal((h, w)) * grains
            if dark_plugs:
                level = 200 * ramp * (1 - 0.65 * grains * texture) * np.where(inside, 0.95, 1.0)
            else:
                level = 20 + 150 * ramp * grains * texture + 8 * inside
            img = ndimage.gaussian_filter(level, 1.2)
            img = rng.poisson(np.clip(img, 0, None) / 2.0) * 2.0  # shot noise
            tif.write(np.clip(img, 0, 255).astype(np.uint8), contiguous=True,
                      metadata={"fps": fps} if k == 0 else None)
    return celerity_m_s, float(np.mean(sorted(seen))), (osc[0] if osc else None)


CASES = {
    "dark_plugs": {},
    "bright_plugs": {"dark_plugs": False, "celerity_m_s": 0.03},
    "thin_tube": {"tube_px": 11.0, "mm_per_px": 0.27, "h": 500},
    "oscillating_6hz": {"celerity_m_s": 0.025, "osc": (6.0, 1.2)},
}


@pytest.mark.parametrize("name", list(CASES))
def test_independent_renderer(tmp_path, name):
    kw = dict(CASES[name])
    rng = np.random.default_rng(2024)
    c, length, f = render(tmp_path / "m.tif", rng=rng, **kw)
    mm_per_px = kw.get("mm_per_px", 0.15)
    s = analyze(tmp_path / "m.tif", AnalysisParams(mm_per_px=mm_per_px)).summary
    assert s["celerity_m_s"] == pytest.approx(c, rel=0.02)
    assert s["plug_length_mm"] == pytest.approx(length, rel=0.03)
    assert s["regime"] == ("oscillating" if f else "propagative")
    if f:
        assert s["oscillation_frequency_hz"] == pytest.approx(f, abs=0.2)
    # the scale from the tube: this renderer's bore is a plain band of tube_px pixels
    tube_px = kw.get("tube_px", 20.0)
    assert s["tube_diameter_px"] == pytest.approx(tube_px, rel=0.04)
    # and the whole measure with the scale taken from the tube (its bore is tube_px * mm_per_px)
    t = analyze(tmp_path / "m.tif", AnalysisParams(tube_diameter_mm=tube_px * mm_per_px)).summary
    assert t["celerity_m_s"] == pytest.approx(c, rel=0.04)
    assert t["plug_length_mm"] == pytest.approx(length, rel=0.05)
