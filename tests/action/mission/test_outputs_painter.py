"""map.png drawn by a forked process (attend.action.mission.map_painter)."""

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


@linux_only
def test_forked_painter_writes_the_same_png_as_drawing_here(tmp_path):
    painter = MapPainter()
    assert painter.pid is not None
    painter.submit(_picture(), tmp_path / "forked.png")
    painter.wait()
    MapPainter(enabled=False).submit(_picture(), tmp_path / "here.png")
    assert (tmp_path / "forked.png").read_bytes() == (tmp_path / "here.png").read_bytes()


@linux_only
def test_painter_reports_the_childs_error_and_closes_cleanly(tmp_path):
    painter = MapPainter()
    painter.submit(_picture(probability="not an image"), tmp_path / "bad.png")
    with pytest.raises(RuntimeError, match="map.png could not be drawn"):
        painter.wait()
    idle = MapPainter()
    pid = idle.pid
    idle.close()  # nothing submitted: the child exits
    assert idle.pid is None
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, 0)
