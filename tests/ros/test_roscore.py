"""The roscore fixture itself: a real master on a free port, ROS's own tools pointed at it."""

from __future__ import annotations

from tests.ros.conftest import Ros, master_answers


def test_master_answers_and_tools_reach_it(ros: Ros) -> None:
    assert master_answers(ros.uri)
    ros.wait_for("roscore's rosout node", lambda: "/rosout/get_loggers" in ros.services())
    res = ros.run(["rostopic", "list"])
    assert "/rosout" in res.stdout.split()
