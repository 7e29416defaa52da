"""Bayesian calibration. Sub-commands:

  sensor   the force→displacement matrix C of a sensor element from a calibration
           campaign (calibration.csv + scene.toml with the nominal C₀)
  neuron   the FA-I neuron's (a, τ, h) and the decoder noise from labelled plate scans (M2)
  sensors  many sensor elements at once, fanned out over dask.distributed

Every fit prints a summary table (mean, sd, 95 % interval, R-hat, bulk ESS per
parameter) and its verdict; with --out DIR it writes posterior.nc, summary.csv and
verdict.json. The exit status is 1 when the posterior fails its diagnostics.

Example:
    feeler simulate datasets-synthetic/sensor-calibration.toml --out runs/cal
    feeler calibrate sensor runs/cal --out runs/m1
"""
from __future__ import annotations

import importlib

__all__ = ["NAME", "HELP", "register", "SUBCOMMANDS"]

NAME = "calibrate"
HELP = "Bayesian calibration: a sensor's matrix (sensor, sensors) or the neuron (neuron)"

# (sub-command, module): each module defines HELP, a docstring and register(parser).
# To add one (e.g. "neuron"), append a line here.
SUBCOMMANDS = [
    ("sensor", "feeler.commands._calibrate_sensor"),
    ("neuron", "feeler.commands._calibrate_neuron"),
    ("sensors", "feeler.commands._calibrate_sensors"),
]


def register(parser) -> None:
    sub = parser.add_subparsers(title="what to calibrate", metavar="WHAT")
    for name, module_name in SUBCOMMANDS:
        module = importlib.import_module(module_name)
        cmd = sub.add_parser(name, help=module.HELP, description=module.__doc__)
        module.register(cmd)
