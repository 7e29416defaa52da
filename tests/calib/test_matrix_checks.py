"""M1's verdict checks, one failing case per branch, and the shipped campaigns passing them."""
import dataclasses
import warnings

import numpy as np
import pytest

from feeler.calib.matrix import CalibrationData, MatrixPrior, fit_matrix
from feeler.calib.matrix.checks import (conflict_problems, design_problems, noise_unit_problems, ppc_problems,
                                        unit_problems)
from feeler.scene import load_scene
from feeler.simulate.calibration import draw_campaign

SCENE = load_scene("datasets-synthetic/sensor-calibration.toml")
PRIOR = MatrixPrior(c0_mm_per_n=SCENE.prior.c0_mm_per_n, rel_sd=SCENE.prior.rel_sd,
                    sigma_f_scale_n=SCENE.prior.sigma_f_scale_n)


def _campaign(scene=SCENE, seed=1):
    u, _, f = draw_campaign(scene, np.random.default_rng(seed))
    return CalibrationData(u, f, np.arange(len(u)))


def _fit(data, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_matrix(data, PRIOR, rng=np.random.default_rng(0), draws=500, **kw)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_shipped_design_on_fresh_seeds_passes(seed):
    scene = dataclasses.replace(SCENE, scene=dataclasses.replace(SCENE.scene, seed=seed))
    res = _fit(_campaign(scene))
    assert res.verdict.ok, res.verdict.problems


def test_near_singular_sensor_is_a_prior_data_conflict():
    c = ((0.30, 0.012, 0.29), (0.015, 0.15, 0.010), (0.29, 0.008, 0.30))          # cond(C) = 59
    scene = dataclasses.replace(SCENE, sensor=dataclasses.replace(SCENE.sensor, c_mm_per_n=c))
    res = _fit(_campaign(scene))
    text = "; ".join(res.verdict.problems)
    assert not res.verdict.ok and "K: row 0 by least squares" in text and "prior-data conflict" in text
    wide = fit_matrix(_campaign(scene), dataclasses.replace(PRIOR, rel_sd=50.0), rng=np.random.default_rng(0))
    assert wide.verdict.ok, wide.verdict.problems                   # a prior that lets the data speak passes


def test_units_um_and_mn_are_named():
    d = _campaign()
    um = _fit(CalibrationData(1000 * d.u_mm, d.f_n, d.point_id))
    assert not um.verdict.ok and "displacements probably in um" in um.verdict.problems[0]
    mn = unit_problems(d.u_mm, 1000 * d.f_n, PRIOR.c0, forward=False)
    assert len(mn) == 1 and "forces probably in mN" in mn[0]
    gf = unit_problems(d.u_mm, 1000 / 9.80665 * d.f_n, PRIOR.c0, forward=False)      # a force gauge in gram-force
    assert len(gf) == 1 and "forces probably in gram-force (expected N; 1 N = 102 gf" in gf[0]
    assert unit_problems(d.u_mm, d.f_n, PRIOR.c0, forward=False) == []
    assert unit_problems(d.f_n, 1000 * d.u_mm, PRIOR.c0, forward=True)[0].startswith("C: the data's compliance is")


@pytest.mark.parametrize("u_scale, f_scale, words", [
    (1.0, 1 / 9.80665, "forces probably in kgf"), (1.0, 1 / 4.448222, "forces probably in lbf"),
    (0.1, 1.0, "displacements probably in cm"), (1.0, 10.0, "or forces 10 times too large"),
    (1 / 25.4, 1.0, "displacements probably in inches")])
def test_smaller_unit_slips_are_named(u_scale, f_scale, words):
    """A force gauge in kgf or lbf moves the compliance by 9.8 or 4.4, under the x30 of the
    usual slips: with K's prior linear (sd 0.5 K0, K/10 at 1.8 sd) both passed with verdict
    ok. Also on a sensor whose true compliance is 30 % above the nominal, and not for a true
    compliance three times the nominal (no unit slip: the prior-data conflict says it)."""
    d = _campaign()
    res = _fit(CalibrationData(u_scale * d.u_mm, f_scale * d.f_n, d.point_id))
    assert not res.verdict.ok and words in res.verdict.problems[0], res.verdict.problems
    soft = dataclasses.replace(SCENE, sensor=dataclasses.replace(
        SCENE.sensor, c_mm_per_n=tuple(tuple(1.3 * v for v in row) for row in PRIOR.c0)))
    d = _campaign(soft)
    assert words in unit_problems(u_scale * d.u_mm, f_scale * d.f_n, PRIOR.c0, forward=False)[0]
    assert words in unit_problems(f_scale * d.f_n, u_scale * d.u_mm, PRIOR.c0, forward=True)[0]


def test_forces_that_do_not_follow_their_displacements_name_no_unit():
    """Force rows shuffled against the displacements: the least-squares compliance has any
    scale (9.1 times the nominal was named "forces probably in kgf"; an outside audit).
    A fit explaining under half the forces' variance says no unit; the same data in kgf,
    rows in order, still do."""
    d = _campaign()
    for seed in range(12):          # 8 of these 12 shuffles were named a unit or a flipped axis before
        shuffled = d.f_n[np.random.default_rng(seed).permutation(len(d.f_n))]
        assert unit_problems(d.u_mm, shuffled, PRIOR.c0, forward=False) == [], seed
    assert "kgf" in unit_problems(d.u_mm, d.f_n / 9.80665, PRIOR.c0, forward=False)[0]


def test_a_compliance_a_few_times_the_nominal_is_no_unit_slip():
    for k in (2.0, 3.0, 1 / 3.0):
        scene = dataclasses.replace(SCENE, sensor=dataclasses.replace(
            SCENE.sensor, c_mm_per_n=tuple(tuple(k * v for v in row) for row in PRIOR.c0)))
        d = _campaign(scene)
        assert unit_problems(d.u_mm, d.f_n, PRIOR.c0, forward=False) == [], k


def test_forces_and_displacements_both_in_another_unit_are_named():
    """mN and µm together leave the compliance as nominal, so the unit check passed; the
    half-normal noise prior (0.1 N) then dragged the force noise from 20 'N' to 3.7 and
    the verdict blamed outliers ("a typo or a slipped contact?"). The scatter names it,
    first, for either regression."""
    d = _campaign()
    both = CalibrationData(1000 * d.u_mm, 1000 * d.f_n, d.point_id)
    for model in ("inverse", "forward"):
        res = _fit(both, model=model)
        assert not res.verdict.ok and res.verdict.problems[0].startswith("sigma: the ")
        assert res.verdict.problems[0].endswith("is the nominal's: forces probably in mN and displacements in um "
                                                "(expected N and mm)")
    assert noise_unit_problems(d.u_mm, d.f_n, PRIOR.sigma_f_scale_n, forward=False) == []
    # a gauge 10x noisier than the prior's scale is not a unit
    noisy = d.f_n + np.random.default_rng(4).normal(0.0, 1.0, d.f_n.shape)
    assert noise_unit_problems(d.u_mm, noisy, PRIOR.sigma_f_scale_n, forward=False) == []


def test_swapped_columns_and_a_flipped_axis_are_named():
    """Forces in the displacement columns and back: the fitted 'compliance' is the
    sensor's stiffness, 20x the nominal compliance (inside the x30 unit check), and the
    verdict was ok. A displacement axis of the opposite sign was a prior-data conflict
    that named neither the axis nor the sign."""
    d = _campaign()
    swapped = _fit(CalibrationData(d.f_n, d.u_mm, d.point_id))
    assert not swapped.verdict.ok
    line = swapped.verdict.problems[0]
    assert "matches the nominal stiffness C0^-1 [4 0 0; 0 5 0; 0 0 4] N/mm" in line and "probably swapped" in line
    assert "\n" not in line
    for axis in range(3):
        u = d.u_mm.copy()
        u[:, axis] *= -1
        (q,) = unit_problems(u, d.f_n, PRIOR.c0, forward=False)
        name = "xyz"[axis]
        assert f"on axis {name} is -" in q and f"u{name}_mm or f{name}_n probably has the opposite sign" in q
    assert unit_problems(d.u_mm, d.f_n, PRIOR.c0, forward=False) == []


@pytest.mark.parametrize("order, words", [
    ([1, 0, 2], "with axes x and y exchanged: the columns ux_mm, uy_mm (or fx_n, fy_n) are probably in the "
                "wrong order"),
    ([0, 2, 1], "with axes y and z exchanged: the columns uy_mm, uz_mm (or fy_n, fz_n)"),
    ([1, 2, 0], "with axes x, y and z exchanged: the columns ux_mm, uy_mm, uz_mm (or fx_n, fy_n, fz_n)"),
])
def test_exchanged_axes_are_named(order, words):
    """fx_n and fy_n written in each other's column: the compliance is C0 with two columns
    exchanged, the default prior is wide enough that no conflict fires, and the verdict
    was ok. The force columns or the displacement columns, or a 3-cycle, say the same."""
    d = _campaign()
    res = _fit(CalibrationData(d.u_mm, d.f_n[:, order], d.point_id))
    assert not res.verdict.ok and len(res.verdict.problems) == 1 and words in res.verdict.problems[0]
    (q,) = unit_problems(d.u_mm[:, order], d.f_n, PRIOR.c0, forward=False)
    assert words.split(":")[0] in q
    tilted = PRIOR.c0 + 0.3 * np.max(PRIOR.c0) * np.array([[0, 1, 0], [1, 0, 0], [0, 0, 0]])   # coupled, not exchanged
    u = d.f_n @ tilted.T
    assert unit_problems(u, d.f_n, PRIOR.c0, forward=False) == []


def test_all_zero_and_unidentified_designs():
    d = _campaign()
    zero = _fit(CalibrationData(0 * d.u_mm, d.f_n, d.point_id))
    assert zero.verdict.problems[0].startswith("K: the displacements are all zero")
    u = d.u_mm.copy()
    u[:, 2] = 0.0
    assert any("z=+1.000" in q for q in design_problems(u, matrix="K", what="displacement", unit="mm"))


def test_conflict_check_exact_on_a_constructed_case():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(40, 3))
    b0 = np.eye(3)
    y = x @ (b0 + 10.0).T + 0.1 * rng.normal(size=(40, 3))           # every row 10 from the prior mean
    assert len(conflict_problems(x, y, b0, 1.0, matrix="K", unit="N/mm")) == 3
    assert conflict_problems(x, y, b0, 100.0, matrix="K", unit="N/mm") == []


def test_posterior_predictive_checks_catch_a_nonlinear_sensor_and_an_outlier():
    d = _campaign()
    k = np.linalg.inv(np.asarray(SCENE.sensor.c_mm_per_n))
    rng = np.random.default_rng(4)
    curved = d.u_mm @ k.T + 40.0 * d.u_mm ** 2 + 0.02 * rng.normal(size=d.u_mm.shape)   # stiffening
    res = _fit(CalibrationData(d.u_mm, curved, d.point_id))
    assert any("lack of fit" in q for q in res.verdict.problems), res.verdict.problems
    spike = d.f_n.copy()
    spike[7, 1] += 0.5                                                               # one 25-sigma reading
    res = _fit(CalibrationData(d.u_mm, spike, d.point_id))
    assert any("largest standardised residual" in q and "axis y" in q and "(data row 8, " in q
               for q in res.verdict.problems), res.verdict.problems                 # names the row to look at
    clean = _fit(d)
    assert clean.verdict.ok
    B = np.tile(np.linalg.lstsq(d.u_mm, d.f_n, rcond=None)[0].T, (50, 1, 1))
    assert ppc_problems(d.u_mm, d.f_n, B, np.full((50, 3), 0.02), np.random.default_rng(5), matrix="K") == []


def test_a_file_appended_to_itself_is_named():
    """Every row twice: the copies halve the intervals as if measured again, and the verdict
    blamed the Gaussian linear model. One line names the copies; a replicated design
    (the same displacement measured again, other forces) is not a copy."""
    d = _campaign()
    twice = CalibrationData(np.vstack([d.u_mm, d.u_mm]), np.vstack([d.f_n, d.f_n]), np.r_[d.point_id, d.point_id])
    res = _fit(twice)
    n = len(d.u_mm)
    assert res.verdict.problems[0] == (
        f"K: {n} of {2 * n} rows repeat an earlier row exactly (point, displacements and forces; e.g. data row {n + 1} "
        f"= data row 1): the file was probably appended to itself, and its copies would count as new measurements; "
        f"keep each measurement once")
    again = _campaign(seed=7)
    replicated = CalibrationData(np.vstack([d.u_mm, d.u_mm]), np.vstack([d.f_n, again.f_n]),
                                 np.r_[d.point_id, d.point_id])
    from feeler.calib.matrix.checks import repeat_problems

    assert repeat_problems(replicated.point_id, replicated.u_mm, replicated.f_n, matrix="K") == []


def test_forces_that_do_not_follow_the_displacements_fail_naming_the_axes():
    """Displacement rows shuffled against the forces: the design still spans every direction
    and a prior wide enough for C0 (sd 2.5 N/mm per entry of K) still holds K's rows near 0,
    so every earlier check passed and the verdict said ok with C[0,0] = -0.8 +- 84 mm/N."""
    data = _campaign()
    mixed = CalibrationData(data.u_mm[np.random.default_rng(3).permutation(len(data.u_mm))], data.f_n,
                            data.point_id)
    res = _fit(mixed)
    lines = [q for q in res.verdict.problems if "do not pin the sign" in q]
    assert len(lines) == 1 and lines[0].startswith("C: the data do not pin the sign of the compliance on axes "), \
        res.verdict.problems
    assert "rows shuffled" in lines[0]
    assert not [q for q in _fit(data).verdict.problems if "sign" in q]


def test_sign_check_on_constructed_draws():
    from feeler.calib.matrix.checks import sign_problems

    c0 = np.diag([0.25, 0.2, 0.25])
    rng = np.random.default_rng(0)
    pinned = c0 + 0.01 * rng.standard_normal((400, 3, 3))
    assert sign_problems(pinned, c0) == []
    loose = pinned.copy()
    loose[:, 1, 1] = 0.05 + 0.1 * rng.standard_normal(400)             # 95 % interval about [-0.15, 0.25]
    (line,) = sign_problems(loose, c0)
    assert line.startswith("C: the data do not pin the sign of the compliance on axis y: 95 % interval C[1,1] [")
    assert "(nominal 0.2) mm/N hold 0" in line
    assert "no draw of the compliance is finite" in sign_problems(np.full((10, 3, 3), np.inf), c0)[0]
