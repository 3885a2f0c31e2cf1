"""scene3D.errors: the helpers that messages share."""

import pytest

from scene3D.errors import plural


@pytest.mark.parametrize("count, noun, expected", [
    (1, "pose", "1 pose"),
    (2, "pose", "2 poses"),
    (0, "pose", "0 poses"),
    (1, "inner corner", "1 inner corner"),
    (4, "inner corner", "4 inner corners"),
    (43, "pairs task", "43 pairs tasks"),
])
def test_plural_puts_the_count_before_the_noun_and_an_s_after_all_but_one(count, noun,
                                                                          expected):
    assert plural(count, noun) == expected
