"""State limits: the master holds a model-exchange instance's state at a bound, passes a fraction of what it
removes to another state, changes nothing at the neutral values, and runs alike in C and in Python."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import REPO
from scipy.integrate import solve_ivp

from dse_runner.errors import DseError
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import Scenario
from dse_runner.simulation.state_limits import StateLimit, parse, split
from dse_runner.simulation.trajectory import Series

TANKS = REPO / "jobs" / "cascaded_tanks" / "multimodel.yaml"
K = {
    "tanks.k1": 0.05,
    "tanks.k2": 0.06,
    "tanks.k3": 0.08,
    "tanks.k4": 0.06,
    "tanks.x1_0": 4.0,
    "tanks.x2_0": 3.0,
}
T = np.arange(0.0, 1200.0 + 4.0, 4.0)
PUMP = np.where((T >= 100.0) & (T < 700.0), 9.0, 2.0)  # a long push fills the upper tank past 12
STOP, STEP = 1200.0, 4.0


def _scenario() -> Scenario:
    return Scenario("pumped", inputs={"tanks.u": Series(T, PUMP, "hold")}, stop_time=STOP, step=STEP)


def test_names_read_back_as_written():
    assert parse("state_max(tanks.x1)") == StateLimit("max", "tanks", "x1")
    assert parse("state_min(x2)") == StateLimit("min", None, "x2")
    assert parse("state_overflow(tanks.x1, x2)") == StateLimit("overflow", "tanks", "x1", "x2")
    for name in ("state_max(tanks.x1)", "state_min(tanks.x2)", "state_overflow(tanks.x1, x2)"):
        assert parse(name).name == name
    assert parse("tanks.k1") is None and parse("output_gain(tanks.y)") is None
    with pytest.raises(DseError, match=r"a state limit is named state_max\(INSTANCE.STATE\)"):
        parse("state_max(tanks.x1, x2)")


def test_values_are_numbers_and_neutral_ones_are_left_out():
    assert split({"state_max(tanks.x1)": math.inf, "state_overflow(tanks.x1, x2)": 0.0, "tanks.k1": 1.0}) == (
        {"tanks.k1": 1.0},
        {},
    )
    with pytest.raises(
        DseError, match=r"state_min\(tanks.x1\): a state limit's value is a finite number, not inf"
    ):
        split({"state_min(tanks.x1)": math.inf})
    with pytest.raises(
        DseError, match=r"an overflow is the fraction of the rate passed on, from 0 to 1 \(got 1.5\)"
    ):
        split({"state_overflow(tanks.x1, x2)": 1.5})


@pytest.mark.parametrize("loop", ["native", "python"])
def test_a_limit_at_its_neutral_value_changes_nothing_bit_for_bit(loop):
    plain = simulate(TANKS, _scenario(), K, loop=loop)
    neutral = simulate(
        TANKS,
        _scenario(),
        {
            **K,
            "state_max(tanks.x1)": math.inf,
            "state_min(tanks.x2)": -math.inf,
            "state_overflow(tanks.x1, x2)": 0.0,
        },
        loop=loop,
    )
    assert plain.trajectory.values.tobytes() == neutral.trajectory.values.tobytes()


def test_the_master_integrates_the_limited_equations():
    """Upper tank held at 12 with 40 % of its overflow falling into the lower one, held at 9:
    against scipy's own integration of the same equations, the pump held over each
    communication step as the master holds it."""
    high1, fraction, high2 = 12.0, 0.4, 9.0
    run = simulate(
        TANKS,
        _scenario(),
        {
            **K,
            "state_max(tanks.x1)": high1,
            "state_overflow(tanks.x1, x2)": fraction,
            "state_max(tanks.x2)": high2,
        },
    )
    k1, k2, k3, k4 = (K[f"tanks.k{i}"] for i in range(1, 5))

    def rhs(u: float):
        def f(t, s):
            d1 = -k1 * math.sqrt(max(s[0], 0.0)) + k4 * u
            d2 = k2 * math.sqrt(max(s[0], 0.0)) - k3 * math.sqrt(max(s[1], 0.0))
            if s[0] >= high1 and d1 > 0:
                d2, d1 = d2 + fraction * d1, 0.0
            if s[1] >= high2 and d2 > 0:
                d2 = 0.0
            return [d1, d2]

        return f

    y, levels = [K["tanks.x1_0"], K["tanks.x2_0"]], [[K["tanks.x1_0"], K["tanks.x2_0"]]]
    for t0, t1 in zip(run.time[:-1], run.time[1:]):
        u = float(PUMP[np.searchsorted(T, t0, side="right") - 1])
        y = solve_ivp(rhs(u), (t0, t1), y, rtol=1e-9, atol=1e-9, max_step=0.5).y[:, -1]
        levels.append(list(y))
    expected = np.array(levels)
    x1, x2 = run.trajectory.column("tanks.x1"), run.trajectory.column("tanks.x2")
    assert x1.max() == pytest.approx(high1, abs=1e-3) and x2.max() == pytest.approx(
        high2, abs=1e-3
    )  # both held
    assert np.sum(x1 >= high1 - 1e-3) > 20 and np.sum(x2 >= high2 - 1e-3) > 20  # for a while, not a touch
    assert np.max(np.abs(x1 - expected[:, 0])) < 2e-3 and np.max(np.abs(x2 - expected[:, 1])) < 2e-3
    without = simulate(TANKS, _scenario(), {**K, "state_max(tanks.x1)": high1, "state_max(tanks.x2)": high2})
    # the overflow is what fills the lower tank to its bound: without it, the lower tank stays below
    assert without.trajectory.column("tanks.x2").max() < high2 - 0.5
    assert without.trajectory.column("tanks.x1").max() == pytest.approx(high1, abs=1e-3)


def test_limits_applied_in_c_are_bit_identical_to_python():
    """The C right-hand side holds and passes on exactly as state_limits.hold does; a second run of the same
    limits at other values (a fit's next point) takes its own values."""
    names = [
        "state_max(tanks.x1)",
        "state_overflow(tanks.x1, x2)",
        "state_max(tanks.x2)",
        "state_min(tanks.x2)",
    ]
    for values in ([12.0, 0.4, 9.0, 3.5], [11.0, 0.9, 8.0, 3.8]):
        python, ours = (
            simulate(TANKS, _scenario(), {**K, **dict(zip(names, values))}, loop=loop)
            for loop in ("python", "native")
        )
        assert python.trajectory.values.tobytes() == ours.trajectory.values.tobytes()
        assert ours.trajectory.column("tanks.x1").max() == pytest.approx(values[0], abs=1e-3)


def test_what_cannot_be_limited_is_refused_by_name():
    with pytest.raises(
        DseError, match=r"instance 'tanks' has no continuous state 'x3' \(its states: x1, x2\)"
    ):
        simulate(TANKS, _scenario(), {"state_max(tanks.x3)": 1.0})
    with pytest.raises(DseError, match=r"an overflow passes into another state than its own"):
        simulate(TANKS, _scenario(), {"state_max(tanks.x1)": 9.0, "state_overflow(tanks.x1, x1)": 0.5})
    watertank = REPO / "jobs" / "watertank" / "multimodel.yaml"
    with pytest.raises(
        DseError, match=r"instance 'tank' is run as co-simulation: it integrates its own states"
    ):
        simulate(watertank, None, {"state_max(tank.level)": 0.1}, stop_time=1.0, step=0.1)
