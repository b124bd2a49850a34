"""The CLI's signal handlers when a signal lands inside a finaliser (``__del__``): Python would swallow
the exception raised there (an "Exception ignored in" traceback on stderr, and the process goes on);
the handler sends the signal again a moment later, so the command still ends as interrupted /
terminated, without a traceback. Run in a subprocess (the signal goes to that process only)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = str(Path(__file__).resolve().parents[1] / "src")

SCRIPT = """
import os, signal, sys, time
from splatplan.cli._process import Terminated, cli_signal_handlers

SIG = signal.{sig}


class Finalised:
    def __del__(self):
        os.kill(os.getpid(), SIG)
        t = time.perf_counter()
        while time.perf_counter() - t < 0.05:  # the handler runs here, inside __del__
            pass


try:
    with cli_signal_handlers():
        x = Finalised()
        del x
        t = time.perf_counter()
        while time.perf_counter() - t < 5.0:
            time.sleep(0.001)
        print("not delivered")
except Terminated as e:
    print("terminated", e.code)
except KeyboardInterrupt:
    print("interrupted")
"""


@pytest.mark.parametrize("sig, want", [("SIGTERM", "terminated 143"), ("SIGINT", "interrupted")])
def test_a_signal_inside_a_finaliser_is_delivered_after_it(sig, want):
    env = {**os.environ, "PYTHONPATH": SRC + (os.pathsep + os.environ["PYTHONPATH"] if os.environ.get("PYTHONPATH") else "")}
    p = subprocess.run([sys.executable, "-c", SCRIPT.format(sig=sig)], capture_output=True, text=True, timeout=60, env=env)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == want
    assert "Exception ignored" not in p.stderr and "Traceback" not in p.stderr, p.stderr


def test_finaliser_frames_are_recognised():
    from splatplan.cli._process import _in_finalizer

    seen = {}

    class Probe:
        def __del__(self):
            seen["inside"] = _in_finalizer(sys._getframe())

    Probe()
    assert seen == {"inside": True}
    assert not _in_finalizer(sys._getframe())
