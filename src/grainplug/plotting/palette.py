"""One colour-blind-safe palette (Okabe & Ito 2008) with a fixed meaning in every figure, video and page.

=========  =========  ==================================================
name       colour     meaning
=========  =========  ==================================================
UPPER      #d55e00    upper (upstream) edge of a plug: vermillion
LOWER      #0072b2    lower (downstream) edge of a plug: blue
FIT        #009e73    a fitted line (mean celerity, a fit against ṁ)
WALL       #e69f00    the tube's walls: orange
PLUG       #000000    plugs (grains) where drawn as a colour: black
BUBBLE     #56b4e9    bubbles where drawn as a colour: sky blue
=========  =========  ==================================================

:data:`GROUPS` colours groups of runs (campaign figures). ``review/static/app.js``
and :mod:`grainplug.overlay` use the same colours.
"""

from __future__ import annotations

UPPER, LOWER, FIT, WALL, PLUG, BUBBLE = "#d55e00", "#0072b2", "#009e73", "#e69f00", "#000000", "#56b4e9"
#: groups of runs, in order
GROUPS = ("#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9", "#f0e442", "#000000")


def bgr(colour: str) -> tuple[int, int, int]:
    """``#rrggbb`` as a (blue, green, red) tuple for OpenCV."""
    c = colour.lstrip("#")
    r, g, b = (int(c[i:i + 2], 16) for i in (0, 2, 4))
    return b, g, r


def foreground() -> str:
    """The colour of text in the style sheet in force (black by default, white on ``dark_background``): for
    data drawn in a neutral colour."""
    import matplotlib as mpl

    return str(mpl.rcParams["text.color"])
