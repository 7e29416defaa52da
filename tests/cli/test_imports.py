"""Commands import only what they use (issue 18 item 1) and say what they do first (issue 16 item 1)."""
import pytest

from tests.cli._run import ROOT, feeler, python_x

HEAVY = ("pymc", "pytensor", "arviz", "arviz_stats", "cv2", "weasyprint", "dask", "distributed")


def _modules_after(argv: list[str]) -> list[str]:
    code = ("import sys\nfrom feeler.cli import main\ntry:\n    main(%r)\nexcept SystemExit:\n    pass\n"
            "print('LOADED', sorted(m for m in sys.modules))" % (argv,))
    out = python_x(code)
    assert out.returncode == 0, out.stderr
    line = next(ln for ln in out.stdout.splitlines() if ln.startswith("LOADED"))
    return eval(line.removeprefix("LOADED "))


def test_import_feeler_and_help_load_nothing_heavy():
    loaded = _modules_after(["--help"])
    assert [m for m in HEAVY if m in loaded] == []
    assert "numpy" not in loaded and "pandas" not in loaded


def test_an_exact_fit_needs_neither_pymc_nor_scipy_stats_nor_dask(tmp_path):
    assert feeler("simulate", "datasets-synthetic/sensor-calibration.toml", "--out", tmp_path / "sc").returncode == 0
    loaded = _modules_after(["calibrate", "sensor", str(tmp_path / "sc"), "--out", str(tmp_path / "fit")])
    assert (tmp_path / "fit" / "posterior.nc").is_file()
    unwanted = tuple(m for m in HEAVY if m != "dask") + ("scipy.stats", "dask.array", "numba")
    assert [m for m in unwanted if m in loaded] == []


def test_first_line_comes_before_the_heavy_imports(tmp_path):
    out = python_x("from feeler.cli import main; main(['calibrate', 'sensor', %r])"
                   % str(ROOT / "nowhere"), "-X", "importtime")
    lines = out.stderr.splitlines()
    first = next(i for i, ln in enumerate(lines) if not ln.startswith("import time:"))
    assert lines[first].startswith("feeler calibrate sensor: fitting ")
    heavy = [i for i, ln in enumerate(lines) if ln.startswith("import time:") and ln.split("|")[-1].strip()
             in ("numpy", "pandas", "xarray")]
    assert heavy and min(heavy) > first


def test_no_progress_means_no_first_line():
    out = feeler("calibrate", "sensor", ROOT / "nowhere", "--no-progress")
    assert out.returncode == 2 and out.stderr.splitlines()[0].startswith("feeler: error: ")


def test_classify_with_a_grid_fit_needs_neither_pymc_nor_arviz_nor_scipy_stats(tmp_path):
    """`classify` decodes with the stored draws: no sampler, no ArviZ, and no scipy.stats
    (0.4 s of imports; the Student-t of the fit's leave-one-out is imported by the fit alone)."""
    assert feeler("simulate", "datasets-synthetic/four-plates.toml", "--out", tmp_path / "fp").returncode == 0
    assert feeler("calibrate", "neuron", tmp_path / "fp", "--out", tmp_path / "m2").returncode == 0
    loaded = _modules_after(["classify", str(tmp_path / "m2"), str(tmp_path / "fp"), "--out", str(tmp_path / "cl")])
    assert (tmp_path / "cl" / "classification.csv").is_file()
    unwanted = tuple(m for m in HEAVY if m not in ("dask", "distributed")) + ("scipy.stats", "matplotlib")
    assert [m for m in unwanted if m in loaded] == []


@pytest.mark.parametrize("argv, line", [
    (["discriminate", "fit-dir", "--scene", "other.toml"], "simulating 2AFC discrimination with the posterior fit-dir"),
    (["classify", "fit-dir", "scans.csv"], "classifying the scans scans.csv"),
    (["simulate", "a.toml", "--out", "x"], "simulating a.toml"),
    (["decode", "fit-dir", "run-dir"], "decoding the run run-dir"),             # it said "working fit-dir"
])
def test_the_first_line_names_what_the_command_works_on(capsys, argv, line):
    """discriminate's first line called the --scene file "the posterior" (an outside audit)."""
    from feeler.cli import _first_line, build_parser

    _first_line(build_parser().parse_args(argv))
    assert capsys.readouterr().err == f"feeler {argv[0]}: {line} (loading libraries) ...\n"
