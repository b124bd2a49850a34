"""Suite-wide test settings."""

import os
import sys

# Tests that plot run headless. The library never picks a matplotlib backend (the CLI does, once
# at start-up: splatplan.cli._common.headless_matplotlib), so the suite picks one here, before any
# test module imports matplotlib.
os.environ["MPLBACKEND"] = "Agg"
if "matplotlib" in sys.modules:
    sys.modules["matplotlib"].use("Agg")

# A shell that starts the suite as a background job (``cmd &`` without job control, ``nohup``)
# hands it SIGINT ignored, and every command the suite spawns inherits that: the tests of Ctrl-C
# handling (OMPL's search, the viewer, the CLI's exit 130) would then wait for a signal that never
# arrives. The suite runs as an interactive process would, however it was started.
import signal  # noqa: E402

if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
