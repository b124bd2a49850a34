"""One guard for requests whose memory (or work) depends on a user's numbers: estimate first,
refuse with a message that names the flag to lower, and only then allocate.

    from splatplan._resources import require_bytes

    n_cells = math.prod(math.ceil(e / spacing) for e in extent)      # a float-safe estimate
    require_bytes(n_cells * 64, "the query grid of eval pr", "--spacing (larger)")
    grid = np.empty((int(n_cells), 3))                                # only now

The memory limit is ``SPLATPLAN_MAX_MEMORY`` (bytes; suffixes K/M/G/T accepted) or, by default,
half the machine's physical memory: a request over it would swap or be killed by the OOM
killer (the 24 GiB shared machines), so it fails fast with :class:`ResourceError` (a
:class:`~splatplan.errors.SplatplanError`: one line on the CLI, exit 2). Callers with their own,
stricter cap (the renderer's ``max_bytes``) pass it as ``limit``.
"""

from __future__ import annotations

import math
import os

from .errors import SplatplanError

__all__ = ["ROLLOUT_BYTES", "ResourceError", "memory_limit", "require_bytes", "require_rollouts", "require_work"]

#: bytes per (sample, step) of an MPPI batch: states, controls, FK of every ellipsoid, metric
#: outputs and cost terms in float64 (an estimate with headroom; the default batches use ~1-10 MB)
ROLLOUT_BYTES = 4096


class ResourceError(SplatplanError):
    """A request would need more memory (or work) than allowed; the message names the flag to lower.

    ``fields``: the config fields to lower (dotted paths within the config that raised it), so the
    command line can name them as its flags."""

    def __init__(self, message: str, fields: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.fields = tuple(fields)


_SUFFIX = {"": 1, "K": 1024, "M": 1024**2, "G": 1024**3, "T": 1024**4}


def memory_limit() -> int:
    """Bytes one request may allocate: ``SPLATPLAN_MAX_MEMORY`` or half the physical memory."""
    text = os.environ.get("SPLATPLAN_MAX_MEMORY", "").strip().upper().removesuffix("B").removesuffix("I")
    if text:
        unit = text[-1] if text[-1] in _SUFFIX else ""
        try:
            return int(float(text[: len(text) - len(unit)]) * _SUFFIX[unit])
        except ValueError:
            raise SplatplanError(f"SPLATPLAN_MAX_MEMORY={os.environ['SPLATPLAN_MAX_MEMORY']!r}: expected bytes, e.g. 8G") from None
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")) // 2
    except (ValueError, OSError, AttributeError):  # not POSIX: a fixed 8 GiB
        return 8 * 1024**3


def _gib(n: float) -> str:
    return f"{n / 1024**3:.3g} GiB" if n < 1e18 else f"{n:.3g} bytes"


def require_bytes(n_bytes: float, what: str, lower: str, limit: int | None = None) -> None:
    """Raise :class:`ResourceError` when ``n_bytes`` (an estimate, may be a huge float or inf)
    exceeds ``limit`` (default :func:`memory_limit`).

    Args:
        n_bytes: estimated bytes of the allocation (compute it in float: no overflow).
        what: what would be allocated ("the query grid of eval pr").
        lower: the flag(s) or option that shrinks it ("--spacing (larger)").
        limit: the cap in bytes (default :func:`memory_limit`).
    """
    cap = memory_limit() if limit is None else int(limit)
    if not (math.isfinite(n_bytes) and n_bytes <= cap):
        raise ResourceError(f"{what} would need about {_gib(n_bytes)}, over the {_gib(cap)} limit; lower {lower}"
                            + ("" if limit is not None else " (or raise SPLATPLAN_MAX_MEMORY)"))


def require_work(n_units: float, max_units: float, what: str, lower: str, fields: tuple[str, ...] = ()) -> None:
    """Raise :class:`ResourceError` when a compute-bound request (``n_units`` of work, e.g. fitted
    ellipsoids x mesh vertices) exceeds ``max_units``: it would run for hours, not fail. ``fields``:
    the config fields ``lower`` names (see :class:`ResourceError`)."""
    if not (math.isfinite(n_units) and n_units <= max_units):
        raise ResourceError(f"{what} is too large ({n_units:.3g} units of work, limit {max_units:.3g}); lower {lower}", fields=fields)


def require_rollouts(n_samples: int, horizon: int, what: str) -> None:
    """The resource guard of an MPPI batch (K samples x T steps), for configs' ``validate()``."""
    require_bytes(float(n_samples) * float(horizon) * ROLLOUT_BYTES, f"{what}: {n_samples:,} samples x {horizon:,} steps of rollouts", "n_samples or horizon")
