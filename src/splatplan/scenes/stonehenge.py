"""Moved to :mod:`splatplan.scenes.builtin.stonehenge`; this name stays so existing imports work.

The module object is the same (``sys.modules`` alias), so private names and monkeypatching keep
working too.
"""

import sys

from .builtin import stonehenge as _impl

sys.modules[__name__] = _impl
