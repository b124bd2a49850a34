"""Suite-wide test settings."""

import os
import sys

# Tests that plot run headless. The library never picks a matplotlib backend (the CLI does, once
# at start-up: splatplan.cli._common.headless_matplotlib), so the suite picks one here, before any
# test module imports matplotlib.
os.environ["MPLBACKEND"] = "Agg"
if "matplotlib" in sys.modules:
    sys.modules["matplotlib"].use("Agg")
