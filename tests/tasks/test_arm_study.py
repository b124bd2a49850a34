"""The arm study's start: the gripper in front of the bin's front wall, below its top, collision-free."""

import numpy as np

from splatplan.eval.arm import START_Q
from splatplan.robots import load_robot
from splatplan.scenes.builtin.tabletop import TARGET_REGION, tabletop_layout


def test_start_is_in_front_of_and_below_the_front_wall_and_free():
    robot = load_robot("panda")
    lay = tabletop_layout(0)
    q = np.asarray(START_Q, np.float64)
    assert np.all(q >= robot.joint_limits[:, 0]) and np.all(q <= robot.joint_limits[:, 1])
    tcp = robot.link_poses(q)[robot.link_names.index("panda_hand_tcp"), :3, 3]
    wall = lay.scene.select(np.array([lab == "wall_front" for lab in lay.scene.labels]))
    wall_x = float(np.min(wall.boxes[:, 0] - wall.boxes[:, 3]))  # robot-side face (axis-aligned box)
    assert tcp[0] < wall_x - 0.05  # on the robot's side of the wall
    assert tcp[2] < lay.front_wall_top - 0.05  # below its top: the target behind it is hidden
    assert tcp[0] < TARGET_REGION[0][0]
    c, qq, a = robot.ellipsoids(q)
    clearance = lay.scene.ellipsoid_clearance(c, qq, a)  # (E,) exact, metres
    assert clearance[~robot.static_ellipsoids].min() > 0.02  # the moving links (link0's ellipsoids are fixed to the base)
