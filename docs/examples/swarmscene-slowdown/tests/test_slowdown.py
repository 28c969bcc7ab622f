"""The plugin honours swarmscene's avoidance contract (the checks every plugin author runs)."""

from swarmscene.testing import check_avoidance

from swarmscene_slowdown.plugin import Slowdown


def test_slowdown_honours_the_avoidance_contract():
    check_avoidance(Slowdown)
    check_avoidance(Slowdown, {"radius": 5.0, "factor": 0.25})
