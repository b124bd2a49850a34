"""The shape the studies E1-E4 share (eval/_study.py): configs, validation, atomic outputs."""

from __future__ import annotations

import dataclasses

import pytest

from splatplan.errors import SplatplanError
from splatplan.eval._study import StudyConfig, check_device, config_dict, write_outputs
from splatplan.eval.conservatism import ConservatismConfig
from splatplan.eval.linearization import LinearizationConfig
from splatplan.eval.pr import PRConfig
from splatplan.eval.throughput import ThroughputConfig

CONFIGS = (PRConfig, ThroughputConfig, ConservatismConfig, LinearizationConfig)


@pytest.mark.parametrize("cls", CONFIGS, ids=lambda c: c.__name__)
def test_every_study_config_has_the_shared_shape(cls):
    assert issubclass(cls, StudyConfig)
    full, quick = cls(), cls.quick_config()
    assert full.quick is False and quick.quick is True and full.device == "auto"
    assert full.validate() is full and quick.validate() is quick
    assert {"device", "quick", "seed"} <= {f.name for f in dataclasses.fields(cls)}
    with pytest.raises(SplatplanError, match=rf"{cls.__name__}\.device 'gpu' not understood"):
        dataclasses.replace(full, device="gpu").validate()
    d = config_dict(quick)
    assert d["quick"] is True and not any(isinstance(v, tuple) for v in d.values())


def test_device_spelling():
    for ok in ("auto", "cpu", "cuda", "cuda:1"):
        check_device(ok, "X")
    for bad in ("", "cuda:", "CPU", "tpu", "cuda:-1", None):
        with pytest.raises(SplatplanError, match="not understood"):
            check_device(bad, "X")


def test_write_outputs_is_atomic_and_lists_what_it_wrote(tmp_path):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(2, 2))
    fig.subplots().plot([0, 1], [1, 0])
    paths = write_outputs(tmp_path, "x", {"a": [1, 2], "b": float("nan")}, "# x\n", (("x.png", fig, 50),))
    assert [p.name for p in paths] == ["x.json", "x.md", "x.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.json", "x.md", "x.png"]  # no temp file left
    assert (tmp_path / "x.md").read_text() == "# x\n" and (tmp_path / "x.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(SplatplanError, match="does not exist"):
        write_outputs(tmp_path / "missing", "x", {}, "")
