"""M1 on the audit's cases (s43 F6, F8-F10): noise-free outputs, a file appended to itself
with its ids renumbered, µm behind an unidentified design, a softer sensor against
swapped columns, and --predict / --nu checked before any work."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from feeler.calib.matrix import CalibrationData, MatrixPrior, NotSampled, fit_matrix
from feeler.calib.matrix.checks import span_unit_problems, unit_problems
from feeler.calib.matrix.degenerate import copy_problems, noise_free_problems
from feeler.scene import load_scene
from feeler.simulate.calibration import draw_campaign
from tests.cli._run import feeler

SCENE = load_scene("datasets-synthetic/sensor-calibration.toml")
C_TRUE = np.asarray(SCENE.sensor.c_mm_per_n)
C0 = np.asarray(SCENE.prior.c0_mm_per_n)
PRIOR = MatrixPrior(c0_mm_per_n=SCENE.prior.c0_mm_per_n, rel_sd=SCENE.prior.rel_sd,
                    sigma_f_scale_n=SCENE.prior.sigma_f_scale_n)
C0_ARGS = ["--c0", *(f"{v:g}" for v in C0.ravel())]


def _campaign(seed: int = 1) -> CalibrationData:
    u, _, f = draw_campaign(SCENE, np.random.default_rng(seed))
    return CalibrationData(u, f, np.arange(len(u)))


def _noise_free(seed: int = 1) -> CalibrationData:
    d = _campaign(seed)
    return CalibrationData(d.u_mm, d.u_mm @ np.linalg.inv(C_TRUE).T, d.point_id)


def _fit(data, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_matrix(data, PRIOR, rng=np.random.default_rng(0), draws=300, **kw)


def _write(path, data: CalibrationData):
    rows = [",".join([str(i)] + [repr(float(v)) for v in (*u, *f)])
            for i, u, f in zip(range(data.n), data.u_mm, data.f_n)]
    path.write_text("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "\n".join(rows) + "\n")
    return path


# --- F6: noise-free outputs ----------------------------------------------------------------

def test_noise_free_outputs_fail_in_one_line_naming_the_noise():
    res = _fit(_noise_free())
    assert not res.verdict.ok
    (line,) = res.verdict.problems
    assert line.startswith("sigma_n[0], sigma_n[1], sigma_n[2]: noise-free: the residuals of fx_n, fy_n, fz_n")
    assert "cannot be pinned" in line and "zero-width" in line and "simulated without noise" in line
    assert _fit(_campaign()).verdict.ok                                     # the noisy campaign passes


def test_noise_free_is_judged_per_axis_and_against_the_data_scale():
    d = _campaign()
    f = d.f_n.copy()
    f[:, 2] = d.u_mm @ np.linalg.inv(C_TRUE)[2]                    # fz computed from the displacements
    (line,) = noise_free_problems(d.u_mm, f, forward=False)
    assert line.startswith("sigma_n[2]: noise-free: the residuals of fz_n ")
    exact = _noise_free()
    for scale in (1e-3, 1.0, 1e3):                                  # relative: any unit, the same verdict
        assert len(noise_free_problems(exact.u_mm, scale * exact.f_n, forward=False)) == 1
    rounded = np.array([[float(f"{v:.6g}") for v in row] for row in exact.f_n])    # a CSV at 6 digits
    assert len(noise_free_problems(exact.u_mm, rounded, forward=False)) == 1
    # noise 1e-4 of the forces (a hundred times quieter than any stage allows) is noise
    quiet = exact.f_n + 1e-4 * np.random.default_rng(2).standard_normal(exact.f_n.shape)
    assert noise_free_problems(exact.u_mm, quiet, forward=False) == []
    (fwd,) = noise_free_problems(exact.f_n, exact.u_mm, forward=True)
    assert fwd.startswith("sigma_mm[0], sigma_mm[1], sigma_mm[2]: noise-free: the residuals of ux_mm")
    one = np.tile(exact.u_mm[:1], (10, 1)), np.tile(exact.f_n[:1], (10, 1))    # one point copied: nothing to judge
    assert noise_free_problems(*one, forward=False) == []


def test_known_noise_sds_give_noise_free_data_their_width():
    res = _fit(_noise_free(), noise_sd=(0.02, 0.02, 0.02))
    assert not any("noise-free" in q for q in res.verdict.problems), res.verdict.problems


@pytest.mark.parametrize("backend, sampler", [("nuts", "sample_nuts"), ("emcee", "sample_emcee")])
def test_noise_free_outputs_start_no_sampler(monkeypatch, backend, sampler):
    import feeler.calib.matrix.fit as fit_module

    def never(*a, **k):
        raise AssertionError("the sampler was started")
    monkeypatch.setattr(fit_module, sampler, never)
    with pytest.raises(NotSampled) as caught:
        fit_matrix(_noise_free(), PRIOR, backend=backend, rng=np.random.default_rng(0), draws=10, tune=10)
    assert caught.value.backend == backend and not caught.value.verdict.ok
    (line,) = caught.value.verdict.problems
    assert "noise-free" in line


# --- F10: copied rows whatever their ids ----------------------------------------------------

def test_a_file_appended_to_itself_with_renumbered_ids_is_named_once():
    d = _campaign()
    ten = CalibrationData(np.tile(d.u_mm, (10, 1)), np.tile(d.f_n, (10, 1)), np.arange(10 * d.n))
    res = _fit(ten)
    assert res.verdict.problems == (
        f"K: every row appears 10 times (displacements and forces; e.g. data rows 1, {d.n + 1}, {2 * d.n + 1}, ... "
        f"are one row): the file was probably appended to itself (its point ids renumbered), and its copies would "
        f"count as new measurements; keep each measurement once",), res.verdict.problems      # no 'lack of fit'
    one = copy_problems(np.tile(d.u_mm[:1], (9, 1)), np.tile(d.f_n[:1], (9, 1)), matrix="K")
    assert one == ["K: all 9 rows hold the same displacements and forces (those of data row 1): one reading "
                   "copied down the file, or a gauge and a stage that were not read?"]
    some = np.r_[np.arange(d.n), [3, 7]]                           # two rows again (a quantised gauge): no copy
    assert copy_problems(d.u_mm[some], d.f_n[some], matrix="K") == []
    again = np.r_[np.arange(d.n), np.arange(d.n), np.arange(5)]          # appended twice, the second time cut
    (line,) = copy_problems(d.u_mm[again], d.f_n[again], matrix="K")
    assert line.startswith(f"K: {d.n + 5} of {2 * d.n + 5} rows repeat an earlier row's displacements and forces")
    fewer = np.r_[np.arange(d.n), np.arange(d.n - 1)]                     # copies below half: not named
    assert copy_problems(d.u_mm[fewer], d.f_n[fewer], matrix="K") == []


def test_noise_free_replicates_are_named_noise_free_not_copies():
    d = _noise_free()
    twice = CalibrationData(np.tile(d.u_mm, (2, 1)), np.tile(d.f_n, (2, 1)), np.arange(2 * d.n))
    (line,) = _fit(twice).verdict.problems
    assert "noise-free" in line


# --- F9: units behind an unidentified design ------------------------------------------------

def test_um_is_named_when_the_design_moves_one_axis_only():
    d = _campaign()
    u = d.u_mm * np.array([0.0, 1.0, 0.0])                         # ux = uz = 0
    f = u @ np.linalg.inv(C_TRUE).T + 0.02 * np.random.default_rng(3).standard_normal(u.shape)
    res = _fit(CalibrationData(1000 * u, f, d.point_id))
    um = [q for q in res.verdict.problems if q.startswith("C: ")]
    assert len(um) == 1 and "along the displacement direction the data pin, (x=+0.000, y=+1.000, z=+0.000)" in um[0]
    assert "displacements probably in um" in um[0]
    assert len([q for q in res.verdict.problems if "do not pin K" in q]) == 2     # the design is still named
    assert span_unit_problems(u, f, C0, forward=False) == []                      # in mm: nothing to name
    fy = d.f_n * np.array([0.0, 1.0, 0.0])                          # forward: forces along y only
    (fwd,) = span_unit_problems(fy, 1000 * fy @ C_TRUE.T, C0, forward=True)
    assert "along the force direction the data pin, (x=+0.000, y=+1.000, z=+0.000)" in fwd
    assert "displacements probably in um" in fwd


# --- F8: a softer sensor is not a swap ------------------------------------------------------

def test_a_much_softer_sensor_is_told_from_swapped_columns():
    d = _campaign()
    (soft,) = unit_problems(d.u_mm, d.f_n / 20, C0, forward=False)
    assert "keeps its pattern" in soft and "softer than the prior's C0" in soft and "probably swapped" not in soft
    (swap,) = unit_problems(d.f_n, d.u_mm, C0, forward=False)
    assert "forces and displacements probably swapped" in swap and "softer" not in swap
    (x32,) = unit_problems(d.u_mm, d.f_n / 32, C0, forward=False)
    assert "times the nominal C0: a sensor about 34x softer" in x32 and "about 1000x" in x32
    (um,) = unit_problems(1000 * d.u_mm, d.f_n, C0, forward=False)
    assert "displacements probably in um" in um and "softer" not in um
    iso = 0.2 * np.eye(3)                                          # one pattern for both: both named
    u = d.f_n @ (iso * 20).T
    (either,) = unit_problems(u, d.f_n, iso, forward=False)
    assert "cannot tell a swap from a softer sensor" in either


# --- through the command line ---------------------------------------------------------------

def test_cli_noise_free_fails_in_one_line_for_every_backend(tmp_path):
    csv = _write(tmp_path / "noisefree.csv", _noise_free())
    for backend in ("exact", "nuts", "emcee"):
        out = feeler("calibrate", "sensor", csv, *C0_ARGS, "--backend", backend, "--no-progress")
        assert out.returncode == 1, out.stderr
        assert "Traceback" not in out.stderr and "R-hat" not in out.stdout
        verdict = out.stdout[out.stdout.index("verdict:"):].splitlines()
        assert verdict[0] == "verdict: FAILED (1 problem)" and len(verdict) == 2, out.stdout
        assert "noise-free" in verdict[1]
        if backend != "exact":
            assert f"backend {backend} not run" in out.stdout


def test_cli_names_copies_and_um_behind_the_design(tmp_path):
    d = _campaign()
    ten = _write(tmp_path / "dup10.csv", CalibrationData(np.tile(d.u_mm, (10, 1)), np.tile(d.f_n, (10, 1)),
                                                          np.arange(10 * d.n)))
    out = feeler("calibrate", "sensor", ten, *C0_ARGS, "--no-progress")
    assert out.returncode == 1 and "  K: every row appears 10 times" in out.stdout
    assert "lack of fit" not in out.stdout
    u = d.u_mm * np.array([0.0, 1000.0, 0.0])
    um = _write(tmp_path / "onlyuy_um.csv", CalibrationData(u, d.f_n, d.point_id))
    out = feeler("calibrate", "sensor", um, *C0_ARGS, "--no-progress")
    assert out.returncode == 1 and "displacements probably in um" in out.stdout


def _refused_before_work(out, *needles):
    assert out.returncode == 2, out.stderr
    assert "Traceback" not in out.stderr and out.stdout == ""                # no header, no table
    assert "fitting M1" not in out.stderr
    errors = [ln for ln in out.stderr.splitlines() if ln.startswith("feeler: ")]
    assert len(errors) == 1 and errors[0].startswith("feeler: error: argument "), out.stderr
    for n in needles:
        assert n in errors[0]


def test_cli_checks_predict_and_nu_before_any_work(tmp_path):
    csv = _write(tmp_path / "cal.csv", _campaign())
    _refused_before_work(feeler("calibrate", "sensor", csv, *C0_ARGS, "--predict", "nan", "0", "0"),
                         "--predict=[nan, 0.0, 0.0]", "three finite forces")
    _refused_before_work(feeler("calibrate", "sensor", csv, *C0_ARGS, "--predict", "1e30", "0", "0"),
                         "--predict=[1e+30, 0.0, 0.0]", "within 10 times the calibrated ones")
    _refused_before_work(feeler("calibrate", "sensor", csv, *C0_ARGS, "--backend", "nuts", "--noise", "student",
                                "--nu", "-2"), "--nu=-2.0", "a finite number > 0")
    _refused_before_work(feeler("calibrate", "sensor", csv, *C0_ARGS, "--noise", "student"),
                         "--backend='exact'", "exact needs noise=gaussian")
    _refused_before_work(feeler("calibrate", "sensor", csv, *C0_ARGS, "--backend", "nuts", "--stage-sd-mm", "-1",
                                "--eiv"), "--stage-sd-mm=-1.0")
    _refused_before_work(feeler("calibrate", "sensor", csv, *C0_ARGS, "--backend", "emcee", "--eiv"),
                         "emcee cannot sample --eiv")
    f_max = float(np.max(np.linalg.norm(_campaign().f_n, axis=1)))
    out = feeler("calibrate", "sensor", csv, *C0_ARGS, "--predict", f"{2 * f_max}", "0", "0", "--no-progress")
    assert out.returncode == 0, out.stderr
    assert "note: |F| = " in out.stdout and "extrapolates the linear matrix to 2 times it" in out.stdout


# --- session 51 audit: a dead or a copied force channel -------------------------------------

def test_a_force_channel_copied_into_another_is_named_not_a_unit_slip():
    """fz a copy of fx (plus 1e-4 N): the least-squares K is singular, C = K^-1 huge, and the
    verdict said 'compliance 2.72e+04 times the nominal: displacements probably in um'."""
    d = _campaign()
    f = d.f_n.copy()
    f[:, 2] = f[:, 0] + np.random.default_rng(3).normal(0, 1e-4, d.n)
    res = _fit(CalibrationData(d.u_mm, f, d.point_id))
    assert not res.verdict.ok
    assert res.verdict.problems[0].startswith("fx_n, fz_n: the two forces move together (correlation 1.000000)")
    assert not any("probably in um" in p for p in res.verdict.problems), res.verdict.problems


def test_a_force_channel_that_never_changes_is_named():
    """fx at 0.1 N in every row: 'about 110x softer ... or a unit' before; now the channel."""
    d = _campaign()
    f = d.f_n.copy()
    f[:, 0] = 0.1
    res = _fit(CalibrationData(d.u_mm, f, d.point_id))
    assert res.verdict.problems[0] == (f"fx_n: the same value (0.1) in all {d.n} rows: a force channel that was not "
                                       "read? The matrix cannot be found along it")
    assert not any("softer" in p or "unit" in p for p in res.verdict.problems), res.verdict.problems


def test_the_campaigns_force_columns_are_far_from_joined():
    """The threshold's margin: the shipped campaign's force columns over 20 seeds."""
    from feeler.calib.matrix.degenerate import JOINED, output_problems

    worst = 0.0
    for seed in range(20):
        f = _campaign(seed).f_n
        r = np.corrcoef(f.T)
        worst = max(worst, float(np.max(np.abs(r[np.triu_indices(3, 1)]))))
        assert output_problems(f) == []
    assert worst < 0.5 < JOINED
