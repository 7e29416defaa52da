"""`feeler simulate --seed N`: other draws from the same scene, recorded in the run's own
scene file so the run is reproduced from it; refused where a scene draws nothing."""
import tomllib
from pathlib import Path

import pytest

from feeler.cli import main
from feeler.simulate import with_seed

ROOT = Path(__file__).resolve().parents[1] / "datasets-synthetic"


@pytest.mark.parametrize("name, data", [("psychophysics-2afc", "trials.csv"),
                                        ("sensor-calibration", "calibration.csv")])
def test_a_seed_gives_other_draws_that_the_run_scene_reproduces(tmp_path, name, data):
    scene = ROOT / f"{name}.toml"
    own, a, b, again = (tmp_path / d for d in ("own", "a", "b", "again"))
    assert main(["simulate", str(scene), "--out", str(own)]) == 0
    assert main(["simulate", str(scene), "--out", str(a), "--seed", "7"]) == 0
    assert main(["simulate", str(scene), "--out", str(b), "--seed", "7"]) == 0
    assert (a / data).read_bytes() == (b / data).read_bytes()
    assert (a / data).read_bytes() != (own / data).read_bytes()
    assert tomllib.loads((a / "scene.toml").read_text())["scene"]["seed"] == 7
    assert main(["simulate", str(a / "scene.toml"), "--out", str(again)]) == 0       # its own file
    assert (again / data).read_bytes() == (a / data).read_bytes()


def test_with_seed_replaces_adds_and_keeps_the_rest():
    text = '# top\n[scene]\nkind = "x"\nseed = 5  # why\n\n[noise]\nseed = 9\n'
    assert with_seed(text, 11) == '# top\n[scene]\nkind = "x"\nseed = 11 # why\n\n[noise]\nseed = 9\n'
    assert with_seed('[scene]\nkind = "x"\n[noise]\nseed = 9\n', 3) == \
        '[scene]\nseed = 3\nkind = "x"\n[noise]\nseed = 9\n'


@pytest.mark.parametrize("name, seed, message", [
    ("finger-steps", "3", "argument --seed=3: a finger-steps scene draws nothing at random"),
    ("psychophysics-2afc", "-1", "argument --seed=-1: an integer >= 0"),
    # written into scene.toml outside TOML's signed 64-bit integers (an outside audit)
    ("four-plates", "99999999999999999999999",
     "argument --seed=99999999999999999999999: an integer from 0 to 2**63-1 = 9223372036854775807"),
    ("sensor-calibration", str(2**63), f"argument --seed={2**63}: an integer from 0 to 2**63-1"),
])
def test_a_seed_where_none_applies_is_one_line_before_any_work(tmp_path, capsys, name, seed, message):
    out = tmp_path / "run"
    assert main(["simulate", str(ROOT / f"{name}.toml"), "--out", str(out), "--seed", seed]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:")]
    assert len(err) == 1 and message in err[0]
    assert not out.exists()


def test_the_largest_seed_is_taken_and_one_more_in_a_scene_file_is_refused(tmp_path):
    from feeler.errors import SceneError
    from feeler.scene import SEED_MAX, load_scene

    out = tmp_path / "run"
    assert main(["simulate", str(ROOT / "psychophysics-2afc.toml"), "--out", str(out), "--seed", str(SEED_MAX),
                 "--no-progress"]) == 0
    assert load_scene(out / "scene.toml").scene.seed == SEED_MAX == 2**63 - 1
    bad = tmp_path / "bad.toml"
    bad.write_text(with_seed((ROOT / "four-plates.toml").read_text(encoding="utf-8"), 2**63), encoding="utf-8")
    with pytest.raises(SceneError, match=r"scene\.seed: 9223372036854775808 out of range: must be <= 9223372036854775807"):
        load_scene(bad)
