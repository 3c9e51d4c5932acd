"""The scale from the tube (issue 16, items 3 and 6) on movies from an independent optical renderer.

``tube_optics.py`` traces rays through the glass with Fresnel reflections and renders the
movie; grainplug's tube model uses closed-form principal rays. Target: the bore within 2 %,
celerity within 3 %, plug length within 5 % — or a warning that the scale is doubtful, never
silently off. The whole matrix is ``benchmarks/accuracy.py --optics`` (docs/accuracy.md).
"""

from __future__ import annotations

import numpy as np
import pytest
from tube_optics import CASES, SUFFIX, Lighting, profiles, render_movie, trace, visible_fraction
from warned import codes

import grainplug as gp
from grainplug.warning_codes import CODES

#: the warnings that say the scale is doubtful: every scale.* code, and a tube cut by the frame (its width, the
#: scale from it, may be wrong)
SCALE_DOUBTS = {c for c in CODES if c.startswith("scale.")} | {"tube.cut_by_frame"}


def test_the_renderer_conserves_energy_and_shows_the_bore_as_the_issue_says():
    x = np.linspace(0.0, 2.74, 800)
    _, escaped = trace(x, inner_radius=1.5, outer_radius=2.75, n_glass=1.47, lighting=Lighting(), bore="air")
    assert escaped.min() > 0.96 and escaped.max() < 1 + 1e-9  # only the dropped weak branches are lost
    expected = {15: 0.65, 20: 0.75, 25: 0.82, 30: 0.87, 35: 0.91, 50: 0.97}
    for beta, share in expected.items():
        assert visible_fraction(profiles(lighting=Lighting("back", beta)), 1.5) == pytest.approx(share, abs=0.01)
    # the wall from the axis out: dark band, bright stripe near 2.06 mm, dark band, rim, background
    p = profiles(lighting=Lighting("back", 25))
    at = {v: float(p.air[np.argmin(np.abs(p.x_mm - v))]) for v in (1.7, 2.06, 2.4, 3.0)}
    assert at[1.7] < 0.1 and at[2.06] > 0.8 and at[2.4] < 0.1 and at[3.0] == pytest.approx(1.0)


SUBSET = ["back-lit, lamp 15 deg", "back-lit, lamp 50 deg", "front-lit, bright plugs", "bore 15 px",
          "tilted -5 deg, lamp 35 deg", "H.264 crf 28", "bore fills 90 % of the frame"]


@pytest.mark.parametrize("name", SUBSET)
def test_never_silently_off(tmp_path, name):
    kw = CASES[name]
    path = tmp_path / f"m{SUFFIX[str(kw.get('fmt', 'tif'))]}"
    truth = render_movie(path, rng=np.random.default_rng(1), **kw)
    for od in (None, float(kw.get("outer_diameter_mm", 5.5))):
        res = gp.analyze(path, fps=truth.fps, tube_outer_diameter_mm=od)
        bore = res.bore.diameter_px / truth.bore_px - 1
        c = res.celerity_m_s / truth.celerity_m_s - 1
        ln = res.plug_length_mm / truth.plug_length_mm - 1
        warned = bool(codes(res) & SCALE_DOUBTS)
        assert (abs(bore) <= 0.02 and abs(c) <= 0.03 and abs(ln) <= 0.05) or warned, (od, bore, c, ln, res.warnings)
        if od and res.tube.back_lit and res.bore.method in ("outer", "outer and stripe"):
            assert abs(bore) <= 0.02  # the outer silhouette (with the stripes), whatever the lamp
