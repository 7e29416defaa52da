"""Scene loading: the shipped four-plates scene, and one negative test per validation branch
of ``feeler/scene.py`` and of the ``robot-scan`` schema (all one-line errors naming file and key)."""
from dataclasses import dataclass
from pathlib import Path

import pytest

from feeler.errors import SceneError
from feeler.scene import load_scene, param, parse_table, scene_as_dict, scene_kinds

SHIPPED = Path(__file__).resolve().parents[1] / "datasets-synthetic" / "four-plates.toml"
TEXT = SHIPPED.read_text(encoding="utf-8")


def variant(tmp_path, old, new, count=1):
    assert old in TEXT, old
    path = tmp_path / "scene.toml"
    path.write_text(TEXT.replace(old, new, count), encoding="utf-8")
    return path


def error_of(path) -> SceneError:
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg
    return info.value


def test_shipped_four_plates_matches_the_paper():
    scene = load_scene(SHIPPED)
    assert "robot-scan" in scene_kinds()
    assert scene.surface.heights_mm == (0.0, 0.05, 0.1, 0.2)
    assert scene.motion.traverse_mm == 10.0 and scene.motion.dt_s == 0.5
    assert scene.neuron.tau_s == 3.0 and scene.repeats.scans_per_plate >= 20
    assert scene.sensor.fidelity == "displacement"
    assert scene_as_dict(scene)["noise"]["uy_sd_mm"] == scene.noise.uy_sd_mm


@pytest.mark.parametrize("old, new, key, words", [
    ("speed_mm_s = 0.5", "speed_mm_s = 0.5\nspeed = 1", "motion.speed", "unknown key"),
    ("tau_s = 3.0", "", "neuron.tau_s", "missing required field"),
    ("traverse_mm = 10.0", 'traverse_mm = "ten"', "motion.traverse_mm", "must be a number"),
    ("seed = 20040501", "seed = 1.5", "scene.seed", "must be an integer"),
    ("speed_mm_s = 0.5", "speed_mm_s = true", "motion.speed_mm_s", "must be a number"),
    ('name = "four-plates"', "name = 4", "scene.name", "must be a string"),
    ("uy_sd_mm = 0.001", "uy_sd_mm = 2.0", "noise.uy_sd_mm", "<= 1.0"),
    ("uy_sd_mm = 0.001", "uy_sd_mm = -0.002", "noise.uy_sd_mm", ">= 0.0"),
    ("speed_mm_s = 0.5", "speed_mm_s = 0.0", "motion.speed_mm_s", "> 0.0"),
    ("uy_sd_mm = 0.001", "uy_sd_mm = nan", "noise.uy_sd_mm", "finite"),
    ("uy_sd_mm = 0.001", "uy_sd_mm = inf", "noise.uy_sd_mm", "finite"),
    ('fidelity = "displacement"', 'fidelity = "hologram"', "sensor.fidelity", "allowed"),
    ('outputs = ["scans"]', 'outputs = ["scans", "movie"]', "scene.outputs[1]", "allowed"),
    ('outputs = ["scans"]', "outputs = []", "scene.outputs", "at least 1"),
    ('outputs = ["scans"]', 'outputs = "scans"', "scene.outputs", "must be a list"),
    ("heights_mm = [0.0, 0.05, 0.1, 0.2]", "heights_mm = [0.0, 9.0]", "surface.heights_mm[1]", "<= 5.0"),
    # impossible combinations (Scene.check)
    ('profile = "step"', 'profile = "step"\ncount = 2', "surface.count", "count = 1"),
    ("traverse_mm = 10.0", "traverse_mm = 0.4", "motion.traverse_mm", "two samples"),
    ("dt_s = 0.5", "dt_s = 0.000001", "motion.dt_s", "1e6 samples"),
    ("position_mm = 5.0", "position_mm = 9.5", "surface.position_mm", "inside the traverse"),
    ("position_mm = 5.0", "position_mm = 0.5", "surface.position_mm", "inside the traverse"),
    ('profile = "step"', 'profile = "grating"\ncount = 5\nspacing_mm = 2.0', "surface.position_mm", "inside"),
    ("uy0_sd_mm = 0.0125", "uy0_sd_mm = 0.02", "probe.uy0_sd_mm", "uy0_mean_mm/3"),
    # a pad wider than the traverse: said as such (it gave an inverted range, "[25.6, -15.6] mm")
    ("pad_width_mm = 1.5", "pad_width_mm = 50", "probe.pad_width_mm", "(51.2 mm) must be shorter than motion.traverse_mm"),
    ("tau_s = 3.0", "tau_s = 25.0", "neuron.tau_s", "shorter than one scan"),
    # a window shorter than one frame (an outside audit: 1e-9 s against 0.5 s frames was simulated): the
    # calibration searches windows from one sample up, so such a truth could never be recovered
    ("tau_s = 3.0", "tau_s = 1e-9", "neuron.tau_s", "one sample (motion.dt_s = 0.5 s)"),
    # one plate listed twice made two 'plates' of one step (an outside audit: it was simulated as asked)
    ("heights_mm = [0.0, 0.05, 0.1, 0.2]", "heights_mm = [0.0, 0.1, 0.1, 0.2]", "surface.heights_mm",
     "0.1 more than once; one entry per plate"),
])
def test_each_rule_names_file_and_key(tmp_path, old, new, key, words):
    err = error_of(variant(tmp_path, old, new))
    assert err.key == key and words in err.problem


def test_a_value_where_a_table_belongs(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text("repeats = 3\n" + TEXT.replace("[repeats]\nscans_per_plate = 24", ""), encoding="utf-8")
    err = error_of(path)
    assert err.key == "repeats" and "must be a table" in err.problem


def test_unknown_kind_missing_kind_bad_toml_missing_and_unreadable_file(tmp_path):
    err = error_of(variant(tmp_path, 'kind = "robot-scan"', 'kind = "submarine"'))
    assert err.key == "scene.kind" and "robot-scan" in err.problem
    err = error_of(variant(tmp_path, 'kind = "robot-scan"', ""))
    assert err.key == "scene.kind" and "missing" in err.problem
    err = error_of(variant(tmp_path, "[motion]", "[motion"))
    assert "not valid TOML" in err.problem
    assert "no such scene file" in error_of(tmp_path / "absent.toml").problem
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(b'[scene]\nname = "\xe9"\n')
    assert "cannot read" in error_of(bad).problem


def test_staircase_and_grating_inside_the_traverse_load(tmp_path):
    s = load_scene(variant(tmp_path, 'profile = "step"', 'profile = "staircase"\ncount = 3\nspacing_mm = 1.0'))
    assert s.last_edge_mm() == 7.0
    g = load_scene(variant(tmp_path, 'profile = "step"', 'profile = "grating"\ncount = 2\nspacing_mm = 1.0'))
    assert g.last_edge_mm() == 6.5


@dataclass(frozen=True)
class _Flags:
    on: bool = param(False, doc="a switch")
    ratio: float = param(0.5, hi=1.0)


def test_bool_field_and_schema_errors():
    assert parse_table(_Flags, {"on": True}, path="x.toml", prefix="").on is True
    with pytest.raises(SceneError, match="true or false"):
        parse_table(_Flags, {"on": 1}, path="x.toml", prefix="")

    @dataclass(frozen=True)
    class Odd:
        thing: dict = param(None)

    with pytest.raises(TypeError, match="unsupported type"):
        parse_table(Odd, {"thing": {}}, path="x.toml", prefix="")
    with pytest.raises(TypeError, match="tuple"):
        param([1, 2])


def test_the_no_snap_control_is_few_scans_without_snapping():
    """The confidence benchmark's control (datasets-synthetic/controls) differs from
    hard/few-scans in what its comment says and nothing else: its name and no touch
    snapping, with the same seed, so the two scenes' replicates are paired."""
    import dataclasses

    root = Path(__file__).resolve().parents[1] / "datasets-synthetic"
    base = load_scene(root / "hard" / "few-scans.toml")
    control = load_scene(root / "controls" / "few-scans-no-snap.toml")
    assert base.probe.snap_prob == 0.5 and control.probe.snap_prob == 0.0
    assert control.scene.seed == base.scene.seed
    assert dataclasses.replace(control, scene=base.scene, probe=dataclasses.replace(control.probe, snap_prob=0.5)) == base
