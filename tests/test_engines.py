"""The execution engines' contract: results in the order of the arguments, progress counted."""

from scene3D.engines import LocalEngine


def _power(base: int, exponent: int) -> int:
    return base**exponent


def test_local_engine_keeps_order_and_reports_progress():
    seen = []
    engine = LocalEngine()
    results = list(engine.map(_power, [(2, 3), (3, 2), (5, 0)], label="powers",
                              progress=lambda label, done, total: seen.append((label, done,
                                                                               total))))
    assert results == [8, 9, 1]
    assert seen == [("powers", 1, 3), ("powers", 2, 3), ("powers", 3, 3)]
    value = {"a": 1}
    assert engine.share(value) is value
