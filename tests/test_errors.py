"""One-line error messages: values shortened so that what names them survives."""
from pathlib import Path

import numpy as np

from feeler.errors import ArgumentError


def test_a_long_path_keeps_its_file_name_wherever_the_checkout_lies():
    for root in ("/work/main", "/home/a-lab-member/projects/tactile/clones/feeler-2026-11-ci-run-1234"):
        path = Path(root) / "datasets-synthetic" / "four-plates.toml"
        for value in (str(path), path):
            msg = str(ArgumentError("--plan", value, "a scan-plan scene, not 'robot-scan'"))
            assert msg.endswith("four-plates.toml': a scan-plan scene, not 'robot-scan'"), msg
            shown = msg.split("=", 1)[1].split(": a scan-plan")[0]
            assert len(shown) <= 60 and shown.startswith("'")


def test_other_long_values_keep_their_start_and_short_ones_are_whole():
    msg = str(ArgumentError("scans", "x" * 100, "fewer"))
    assert msg == f"argument scans='{'x' * 56}...: fewer"
    assert str(ArgumentError("tau", np.float64(np.inf), "finite")) == "argument tau=inf: finite"
    assert str(ArgumentError("--plan", "/tmp/p.toml", "a plan")) == "argument --plan='/tmp/p.toml': a plan"


def test_a_missing_argument_is_named_without_a_value():
    assert str(ArgumentError("--c0", None, "needed: give --c0")) == "argument --c0: needed: give --c0"
    assert str(ArgumentError("--c0", 0, "> 0")) == "argument --c0=0: > 0"


def test_a_value_in_words_is_not_cut_mid_word():
    """'4000 of 4000 draws with a non-finite or zero-spread deco...' (an outside audit): a
    value described in words is shown whole; a long value without spaces is still cut."""
    words = "4000 of 4000 draws with a non-finite or zero-spread decoder"
    assert str(ArgumentError("posterior", words, "a fit whose plates can be decoded")) == \
        f"argument posterior='{words}': a fit whose plates can be decoded"
