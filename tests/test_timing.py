"""scene3D.engines.timing: seconds per stage, on a fake clock so that the sums are exact."""

import pytest

from scene3D.engines import timing
from scene3D.engines.timing import StageTimer


@pytest.fixture
def clock(monkeypatch):
    """A clock that only moves when told: ``clock.tick(seconds)``."""

    class Clock:
        now = 100.0

        def tick(self, seconds: float) -> None:
            self.now += seconds

    c = Clock()
    monkeypatch.setattr(timing.time, "perf_counter", lambda: c.now)
    return c


def test_a_stage_that_runs_again_adds_to_its_seconds(clock):
    timer = StageTimer()
    with timer.stage("matching"):
        clock.tick(2.0)
    clock.tick(50.0)  # outside every stage: counted nowhere
    with timer.stage("registration"):
        clock.tick(0.5)
    with timer.stage("matching"):
        clock.tick(3.0)
    assert timer.seconds == {"matching": 5.0, "registration": 0.5}
    assert list(timer.seconds) == ["matching", "registration"]  # first seen first
    assert timer.total_s == 5.5


def test_declared_stages_keep_their_place_whatever_order_they_run_in(clock):
    timer = StageTimer(["features", "matching"])
    with timer.stage("checks"):
        clock.tick(1.0)
    timer.declare("tracks", "matching", "checks", "lens")
    with timer.stage("tracks"):
        clock.tick(4.0)
    assert list(timer.seconds) == ["features", "matching", "checks", "tracks", "lens"]
    assert timer.seconds == {"features": 0.0, "matching": 0.0, "checks": 1.0, "tracks": 4.0,
                             "lens": 0.0}


def test_a_nested_stage_pauses_the_outer_one_so_each_second_counts_once(clock):
    timer = StageTimer()
    with timer.stage("checks"):
        clock.tick(1.0)
        with timer.stage("tracks"):
            clock.tick(2.0)
            with timer.stage("matching"):
                clock.tick(4.0)
            clock.tick(8.0)
        clock.tick(16.0)
    assert timer.seconds == {"matching": 4.0, "tracks": 10.0, "checks": 17.0}
    assert timer.total_s == 31.0  # the wall time of the outer block


def test_a_stage_nested_in_itself_counts_its_seconds_once(clock):
    timer = StageTimer()
    with timer.stage("matching"):
        clock.tick(1.0)
        with timer.stage("matching"):
            clock.tick(2.0)
    assert timer.seconds == {"matching": 3.0}


def test_a_stage_left_by_an_exception_still_records_its_time(clock):
    timer = StageTimer()
    with pytest.raises(ValueError, match="no pair"):
        with timer.stage("registration"):
            with timer.stage("tracks"):
                clock.tick(1.5)
                raise ValueError("no pair")
    with timer.stage("checks"):  # and the timer goes on afterwards
        clock.tick(0.25)
    assert timer.seconds == {"tracks": 1.5, "registration": 0.0, "checks": 0.25}


def test_seconds_is_a_copy_and_add_takes_outside_measurements(clock):
    timer = StageTimer(["features"])
    seconds = timer.seconds
    seconds["features"] = 99.0
    timer.add("features", 0.75)
    timer.add("lens", 2)
    assert timer.seconds == {"features": 0.75, "lens": 2.0}
