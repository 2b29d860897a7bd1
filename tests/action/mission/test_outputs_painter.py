"""map.png and map.tif written by a forked process (attend.action.mission.map_painter)."""

import os
import sys

import numpy as np
import pytest

from attend.action.mission.map_painter import MapPainter
from attend.action.mission.map_plot import MapPicture

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the painter forks on Linux only")


def _picture(**changes) -> MapPicture:
    square = np.array([[-50.0, -50.0], [50.0, -50.0], [50.0, 50.0], [-50.0, 50.0], [-50.0, -50.0]])
    fields = dict(probability=np.full((20, 20), 1e-3), extent_m=(-50.0, 50.0, -50.0, 50.0), area_rings=[square],
                  no_fly_rings=[], uav_names=["uav1"], flown=[np.zeros((2, 2))], routes=[np.array([[0.0, 0.0], [10.0, 5.0]])],
                  homes_m=np.zeros((1, 2)), targets_m=np.array([[5.0, 5.0]]), title="test")
    fields.update(changes)
    return MapPicture(**fields)


def _tif_job(path):
    probability = np.full((6, 8), 0.25)
    probability[0, 0] = np.nan
    return ("tif", (probability, (100.0, 200.0), 2.0, 'LOCAL_CS["metres"]'), path)


@linux_only
def test_forked_painter_writes_the_same_files_as_writing_here(tmp_path):
    painter = MapPainter()
    assert painter.pid is not None
    painter.submit([("png", _picture(), tmp_path / "forked.png"), _tif_job(tmp_path / "forked.tif")])
    forked = painter.wait()
    here = MapPainter(enabled=False)
    here.submit([("png", _picture(), tmp_path / "here.png"), _tif_job(tmp_path / "here.tif")])
    assert here.wait() == {"here.png": None, "here.tif": None}
    assert forked == {"forked.png": None, "forked.tif": None}
    assert (tmp_path / "forked.png").read_bytes() == (tmp_path / "here.png").read_bytes()
    assert (tmp_path / "forked.tif").read_bytes() == (tmp_path / "here.tif").read_bytes()


@linux_only
def test_painter_reports_the_childs_errors_and_closes_cleanly(tmp_path):
    painter = MapPainter()
    painter.submit([("png", _picture(probability="not an image"), tmp_path / "bad.png"), _tif_job(tmp_path / "ok.tif")])
    results = painter.wait()
    assert results["ok.tif"] is None and results["bad.png"].split(":")[0] in ("TypeError", "ValueError", "AttributeError")
    idle = MapPainter()
    pid = idle.pid
    idle.close()  # nothing submitted: the child exits
    assert idle.pid is None
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, 0)
