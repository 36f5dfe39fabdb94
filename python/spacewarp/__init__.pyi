"""Type stubs of the spacewarp package, written by python/tools/make_stubs.py:
the extension's API (_spacewarp.pyi) and the property kit spacewarp.testing (typed inline)."""

from . import testing as testing
from ._spacewarp import *
from ._spacewarp import __version__ as __version__
from . import _spacewarp as _spacewarp

__all__ = ["__version__", "testing"]
__all__ += _spacewarp.__all__
