"""Layout files of the optical sensor: the shipped one, round trip, every validation branch."""
import re
from pathlib import Path

import pytest

from feeler.errors import DataFileError, SceneError
from feeler.models.optics import grid_layout, layout_toml, load_layout

SHIPPED = Path(__file__).resolve().parents[1] / "datasets-synthetic" / "layouts" / "sensor-16.toml"

GOOD = """[layout]
name = "two"
width_px = 200
height_px = 100
window_px = 10

[[element]]
region = [0, 0, 100, 100]
feelers = [[70, 70], [70, 30], [30, 70], [30, 30]]

[[element]]
region = [100, 0, 100, 100]
feelers = [[170, 70], [170, 30], [130, 70], [130, 30]]
"""


def write(tmp_path, text):
    path = tmp_path / "layout.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_shipped_layout_is_the_16_element_grid():
    layout = load_layout(SHIPPED)
    assert (layout.width_px, layout.height_px, len(layout.elements)) == (640, 480, 16)
    assert layout.centres_px.shape == (16, 4, 2)
    assert layout.elements == grid_layout().elements


def test_layout_toml_round_trip(tmp_path):
    layout = grid_layout(2, 3, width_px=300, height_px=200, window_px=12, offset_px=(20, 20))
    assert load_layout(write(tmp_path, layout_toml(layout))) == layout
    assert len(load_layout(write(tmp_path, GOOD)).elements) == 2


@pytest.mark.parametrize("old, new, key, problem", [
    ("region = [100, 0, 100, 100]", "region = [90, 0, 100, 100]", "element[1].region", "overlaps element[0]"),
    ("region = [100, 0, 100, 100]", "region = [110, 0, 100, 100]", "element[1].region", "leaves the 200×100 frame"),
    ("region = [0, 0, 100, 100]", "region = [0, 0, 0, 100]", "element[0].region", "must be > 0"),
    ("[[70, 70], [70, 30], [30, 70], [30, 30]]", "[[95, 70], [70, 30], [30, 70], [30, 30]]",
     "element[0].feelers[0]", "not inside region"),
    ("[[70, 70], [70, 30], [30, 70], [30, 30]]", "[[70, 70], [70, 30], [30, 70]]",
     "element[0].feelers", "needs 4 centres"),
    ("[[70, 70], [70, 30], [30, 70], [30, 30]]", "[[45, 70], [45, 30], [30, 70], [30, 30]]",
     "element[0].feelers", "windows"),
    ("[[70, 70], [70, 30], [30, 70], [30, 30]]", "[[30, 70], [30, 30], [70, 70], [70, 30]]",
     "element[0].feelers", "order must be"),
    ("region = [0, 0, 100, 100]", "region = [0, 0, 100]", "element[0].region", "4 integers"),
    ("region = [0, 0, 100, 100]", "region = [0, 0, 100.5, 100]", "element[0].region", "4 integers"),
    ("feelers = [[70, 70], [70, 30], [30, 70], [30, 30]]", 'feelers = "x"', "element[0].feelers", "list of"),
    ("[[70, 70], [70, 30], [30, 70], [30, 30]]", '[[70, "a"], [70, 30], [30, 70], [30, 30]]',
     "element[0].feelers[0]", "2 numbers"),
    ("width_px = 200", "width_px = 200.0", "layout.width_px", "integer"),
    ("window_px = 10", "window_px = 0", "layout", "must be > 0"),
    ('[layout]\nname = "two"', '[lay]\nname = "two"', "layout", "missing [layout]"),
])
def test_layout_validation(tmp_path, old, new, key, problem):
    assert old in GOOD
    path = write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(SceneError, match=re.escape(problem)) as info:
        load_layout(path)
    assert info.value.key == key and info.value.path == str(path)
    assert "\n" not in str(info.value)


def test_layout_without_elements(tmp_path):
    with pytest.raises(SceneError, match="missing \\[\\[element\\]\\]"):
        load_layout(write(tmp_path, GOOD.split("[[element]]")[0]))
    with pytest.raises(SceneError, match="at least one element"):
        load_layout(write(tmp_path, "element = []\n" + GOOD.split("[[element]]")[0]))


def test_layout_file_problems(tmp_path):
    with pytest.raises(DataFileError, match="no such layout file"):
        load_layout(tmp_path / "absent.toml")
    with pytest.raises(DataFileError, match="not a readable TOML"):
        load_layout(write(tmp_path, "[layout\nwidth_px = "))
