"""Heavy modules imported on first use.

``scipy.ndimage`` alone takes ~0.2 s to import (scipy's array-API machinery). The
analysis modules reach it through the proxies below, so that importing them is
cheap where no filter runs: the figure helper process, which imports
:mod:`grainplug.analysis` only to unpickle a result, and commands such as
``grainplug info``. The first attribute looked up imports the module; the
attribute is then kept on the proxy.
"""

from __future__ import annotations

import importlib
from typing import Any


class LazyModule:
    """Stands for the module ``name`` and imports it when an attribute is first asked for."""

    def __init__(self, name: str) -> None:
        self._name = name

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__"):
            raise AttributeError(attr)
        value = getattr(importlib.import_module(self._name), attr)
        setattr(self, attr, value)  # found directly from now on
        return value

    def __repr__(self) -> str:
        return f"<lazy module {self._name!r}>"


ndimage = LazyModule("scipy.ndimage")
special = LazyModule("scipy.special")
skimage_filters = LazyModule("skimage.filters")
