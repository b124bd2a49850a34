"""Built-in scenes: analytic primitives with an exact signed distance, and splats sampled on them."""

from . import primitives, stonehenge
