"""One negative test per validation branch of the neuron core."""
import numpy as np
import pytest

from feeler.errors import ArgumentError, InputError
from feeler.models.neuron import FA1Stream, peak_pulse_density, pulse_density, window_sum

T = np.arange(5) * 0.5
E = np.arange(5) * 0.1


def call(**kw):
    args = dict(strain=E, t=T, a=1.0, tau=1.0, h=0.0)
    args.update(kw)
    s, t = args.pop("strain"), args.pop("t")
    return pulse_density(s, t, **args)


@pytest.mark.parametrize("kw, name", [
    (dict(a=0.0), "a"), (dict(a=-1.0), "a"), (dict(a=float("nan")), "a"), (dict(a="x"), "a"),
    (dict(tau=0.0), "tau"), (dict(tau=float("inf")), "tau"),
    (dict(h=-0.1), "h"),
    (dict(kernel="gauss"), "kernel"),
    (dict(strain=np.array(["a"] * 5)), "strain"),
    (dict(strain=np.float64(1.0)), "strain"),
    (dict(strain=E, weights=[1.0]), "strain"),           # weights need (..., n_rec, n_time)
    (dict(t=T.reshape(1, 5)), "t"),
    (dict(t=np.array(["a"] * 5)), "t"),
    (dict(t=T[:4]), "t"),
    (dict(t=np.array([0, 1, np.nan, 3, 4.0])), "t"),
    (dict(t=np.array([0, 1, 1, 3, 4.0])), "t"),
    (dict(t=np.array([0, 2, 1, 3, 4.0])), "t"),
    (dict(strain=np.array([0, 1, np.nan, 3, 4.0])), "strain"),
    (dict(strain=np.array([0, 1, np.inf, 3, 4.0])), "strain"),
    (dict(strain=np.array([np.nan, 1, 2, 3, 4.0])), "strain"),
    (dict(strain=np.array([-1e308, 1e308, 0, 0, 0])), "strain"),  # increments overflow
    (dict(strain=np.stack([E, E]), weights=[1.0, 2.0, 3.0]), "weights"),
    (dict(strain=np.stack([E, E]), weights=[1.0, np.nan]), "weights"),
])
def test_bad_argument_is_a_one_line_value_error_naming_it(kw, name):
    with pytest.raises(ArgumentError) as info:
        call(**kw)
    err = info.value
    assert isinstance(err, ValueError) and isinstance(err, InputError)
    assert err.name == name
    assert "\n" not in str(err) and str(err).startswith(f"argument {name}=")


def test_nan_in_the_exponential_kernel_is_caught_too():
    with pytest.raises(ArgumentError, match="strain"):
        call(strain=np.array([0, 1, np.nan, 3, 4.0]), kernel="exponential")


def test_stream_times_must_continue():
    s = FA1Stream(a=1, tau=1, h=0)
    s.push(T, E)
    with pytest.raises(ArgumentError, match="previous chunk"):
        s.push(T, E)


def test_stream_leading_shape_is_fixed():
    s = FA1Stream(a=1, tau=1, h=0)
    s.push(T, np.stack([E, E]))
    with pytest.raises(ArgumentError, match="leading shape"):
        s.push(T + 10, np.stack([E, E, E]))


def test_stream_checks_its_parameters():
    with pytest.raises(ArgumentError, match="tau"):
        FA1Stream(a=1, tau=-1, h=0)
    with pytest.raises(ArgumentError, match="kernel"):
        FA1Stream(a=1, tau=1, h=0, kernel="box")
    with pytest.raises(ArgumentError, match="weights"):
        FA1Stream(a=1, tau=1, h=0, weights=[1, 2]).push(T, np.stack([E, E, E]))


def test_window_sum_checks_tau_and_kernel():
    with pytest.raises(ArgumentError, match="tau"):
        window_sum(E, T, tau=0)
    with pytest.raises(ArgumentError, match="kernel"):
        window_sum(E, T, tau=1, kernel=None)


@pytest.mark.parametrize("a, h, name", [(np.array([1.0, 0.0]), 0.0, "a"),
                                        (1.0, np.array([0.0, -1.0]), "h"),
                                        (np.nan, 0.0, "a")])
def test_fast_path_checks_the_domain(a, h, name):
    with pytest.raises(ArgumentError) as info:
        peak_pulse_density(np.ones(3), a, h)
    assert info.value.name == name


def test_draws_that_do_not_broadcast_against_the_records_are_named():
    """1-D draws against a batch of records raised numpy's "operands could not be broadcast"
    (an outside walk through the README's snippet); (n_draws, 1) is the way, and it says so."""
    with pytest.raises(ArgumentError, match=r"\(n_draws, 1\)") as info:
        peak_pulse_density(np.ones(2), np.ones(3), np.zeros(3))
    assert info.value.name == "a, h" and "(2,)" in str(info.value)
    assert peak_pulse_density(np.ones(2), np.ones((3, 1)), np.zeros((3, 1))).shape == (3, 2)


# a record this long is cut across the threads, each checking its own piece of t
LONG = 300_001


@pytest.mark.parametrize("where", [1, LONG // 2, LONG // 2 + 1, LONG - 1])
@pytest.mark.parametrize("bad", ["nan", "inf", "repeat", "back"])
def test_long_record_names_the_bad_time_checked_inside_the_threads(where, bad):
    t = np.arange(LONG) * 1e-3
    t[where] = {"nan": np.nan, "inf": np.inf, "repeat": t[where - 1], "back": t[where - 1] - 1e-3}[bad]
    with pytest.raises(ArgumentError, match=rf"argument t=.* at index {where}\b"):
        pulse_density(np.arange(LONG) * 0.1, t, a=1.0, tau=0.3, h=0.0)


@pytest.mark.parametrize("where", [0, 5, LONG // 2, LONG - 1])
def test_long_record_names_the_bad_strain_sample(where):
    eps = np.random.default_rng(where).normal(size=LONG).cumsum()
    eps[where] = np.nan
    with pytest.raises(ArgumentError, match=rf"argument strain='nan at index \({where},\)'"):
        pulse_density(eps, np.arange(LONG) * 1e-3, a=1.0, tau=0.3, h=0.0)
