"""The paper's robot result (§5, Figs 7-9) reproduced on the shipped ``four-plates`` scene.

- ΔU_y jumps at the step in proportion to the step height (1:2:4 within 20 %; Fig. 7);
- the raw U̇_y peak does not reliably order the 0.05 and 0.1 mm plates (2AFC proportion
  correct < 0.8; Fig. 8) while the neuron's peak z does (>= 0.95);
- z has a single peak, at the step (Fig. 9): every scan of the 0.1 and 0.2 mm plates and
  the mean traces of 0.1 and 0.2 mm stay below half their step peak elsewhere; on the
  0.05 mm plate the breakaway at slide onset leaves a secondary bump at the start, and
  the test asks only that the mean trace peaks at the step.
"""
from pathlib import Path

import numpy as np
import pytest

from feeler.datasets import proportion_correct, strain
from feeler.scene import load_scene
from feeler.simulate import features_of, simulate_scans

SHIPPED = Path(__file__).resolve().parents[1] / "datasets-synthetic" / "four-plates.toml"


@pytest.fixture(scope="module")
def run():
    scene = load_scene(SHIPPED)
    scans, touches = simulate_scans(scene)
    return scene, scans, features_of(scene, scans)


def by_plate(scans, values, step):
    return values[scans.step_mm == step]


def test_delta_uy_jumps_in_proportion_to_the_step(run):
    scene, scans, f = run
    jumps = [by_plate(scans, f.jump_uy_mm, s).mean() for s in (0.05, 0.1, 0.2)]
    ratios = np.array(jumps) / jumps[0]
    np.testing.assert_allclose(ratios, [1, 2, 4], rtol=0.2)
    # and the jump is where the step is: mean ΔU_y before/after the step position
    pad = scene.probe.pad_width_mm
    for s in (0.05, 0.1, 0.2):
        sel = scans.step_mm == s
        duy = scans.uy_mm[sel] - scans.uy_mm[sel, :1]
        x = scans.x_mm[sel]
        before = duy[(x > 2.0) & (x < 5.0 - pad)].mean()
        after = duy[x > 5.0 + pad].mean()
        assert after - before == pytest.approx(s, rel=0.2)


def test_raw_rate_cannot_order_005_and_010_but_peak_z_can(run):
    _, scans, f = run
    raw = proportion_correct(by_plate(scans, f.peak_rate_uy_mm_s, 0.05), by_plate(scans, f.peak_rate_uy_mm_s, 0.1))
    z = proportion_correct(by_plate(scans, f.peak_z, 0.05), by_plate(scans, f.peak_z, 0.1))
    assert raw < 0.8
    assert z >= 0.95


def test_z_has_a_single_peak_at_the_step(run):
    from feeler.models import neuron

    scene, scans, _ = run
    nrn, pad, pos = scene.neuron, scene.probe.pad_width_mm, scene.surface.position_mm
    z = neuron.pulse_density(strain(scans.uy_mm, nrn.length_mm), scans.t_s[0], a=nrn.a, tau=nrn.tau_s, h=nrn.h)
    # the step zone: the face touches the step, plus the window τ after it has crossed
    reach_mm = scene.motion.speed_mm_s * nrn.tau_s
    zone = (scans.x_mm >= pos - pad / 2 - 0.5) & (scans.x_mm <= pos + pad / 2 + reach_mm + 0.5)
    for s in (0.1, 0.2):                       # every single scan peaks at the step
        sel = scans.step_mm == s
        assert np.all(np.argmax(z[sel], axis=1) == np.argmax(np.where(zone[sel], z[sel], -1), axis=1))
    for s, limit in ((0.05, 1.0), (0.1, 0.5), (0.2, 0.5)):   # the mean trace (Fig. 9) too
        sel = scans.step_mm == s
        mean_z, in_zone = z[sel].mean(axis=0), zone[sel].mean(axis=0) > 0.5
        assert mean_z[~in_zone].max() < limit * mean_z[in_zone].max()
