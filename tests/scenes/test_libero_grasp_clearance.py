"""The grasp point over a LIBERO object moves off centre only when the open gripper would land on a neighbour."""

from __future__ import annotations

import numpy as np

from scenes.libero.grasp_clearance import PAD_HALF, STEP, blocked, grasp_offset

# a Panda-like open gripper relative to its grip site: the hand (20 cm along the closing axis y) and two fingers
GRIP_LO = np.array([[-0.033, -0.104, 0.045], [-0.01, 0.04, -0.02], [-0.01, -0.06, -0.02]])
GRIP_HI = np.array([[0.033, 0.104, 0.12], [0.01, 0.06, 0.045], [0.01, -0.04, 0.045]])
# cream_cheese at pick_y -2, episode 1, on the complete tree: the box lying flat and the tomato-sauce can 5 mm away
CENTRE = np.array([0.0545, -0.1526, 0.01])
HALF = np.array([0.0405, 0.0215])
CAN_LO, CAN_HI = np.array([[0.069, -0.241, 0.0]]), np.array([[0.132, -0.179, 0.076]])


def test_a_clear_centre_stays_centred():
    none = np.zeros((0, 3))
    assert grasp_offset(GRIP_LO, GRIP_HI, none, none, CENTRE, HALF).tolist() == [0.0, 0.0]
    far_lo, far_hi = CAN_LO + [0.3, 0.0, 0.0], CAN_HI + [0.3, 0.0, 0.0]
    assert grasp_offset(GRIP_LO, GRIP_HI, far_lo, far_hi, CENTRE, HALF).tolist() == [0.0, 0.0]


def test_a_hand_over_a_taller_neighbour_moves_along_the_object_away_from_it():
    assert blocked(GRIP_LO, GRIP_HI, CAN_LO, CAN_HI, CENTRE)  # the hand rests on the can's top
    dx, dy = grasp_offset(GRIP_LO, GRIP_HI, CAN_LO, CAN_HI, CENTRE, HALF)
    assert dx < 0 and abs(dx) <= HALF[0] - PAD_HALF  # away from the can, the pads still on the box
    assert abs(dy) <= 0.04 - HALF[1]
    assert not blocked(GRIP_LO, GRIP_HI, CAN_LO, CAN_HI, CENTRE + [dx, dy, 0.0])
    # the smallest such move: one grid step less along x is still blocked
    assert blocked(GRIP_LO, GRIP_HI, CAN_LO, CAN_HI, CENTRE + [dx + STEP, dy, 0.0])


def test_no_clear_point_on_the_object_keeps_the_centre():
    wall_lo, wall_hi = (
        np.array([[-1.0, -0.25, 0.0]]),
        np.array([[1.0, -0.175, 0.2]]),
    )  # a neighbour along all of it
    assert grasp_offset(GRIP_LO, GRIP_HI, wall_lo, wall_hi, CENTRE, HALF).tolist() == [0.0, 0.0]


def test_an_open_topped_object_is_pinched_at_its_clear_wall():
    """The black bowl (10.6 cm, wider than the open fingers) is grasped at a wall's middle, the side clear of the
    neighbours first; without a wall found (a solid object) there is no rim grasp."""
    from scenes.libero.grasp_clearance import rim_offset

    none = np.zeros((0, 3))
    assert rim_offset(GRIP_LO, GRIP_HI, none, none, CENTRE, []) is None
    assert rim_offset(GRIP_LO, GRIP_HI, none, none, CENTRE, [0.05, -0.049]).tolist() == [0.0, 0.05]
    # a tall neighbour beyond the +y wall blocks the hand there: the -y wall is pinched
    lo, hi = CENTRE + np.array([[-0.05, 0.1, -0.01]]), CENTRE + np.array([[0.05, 0.2, 0.3]])
    assert blocked(GRIP_LO, GRIP_HI, lo, hi, CENTRE + [0.0, 0.05, 0.0])
    assert rim_offset(GRIP_LO, GRIP_HI, lo, hi, CENTRE, [0.05, -0.049]).tolist() == [0.0, -0.049]
    # both sides blocked: the first wall still
    assert rim_offset(GRIP_LO, GRIP_HI, lo - [0, 0.4, 0], hi, CENTRE, [0.05, -0.049]).tolist() == [0.0, 0.05]
