"""The dual carry's values (m, rad, s, kg), checked against the robots' kinematics in tests/test_carry.py.

The robots are the handover scene's (:func:`coopsim.tasks.scene.scaras`: SCARA #1 at the origin with
``L_base = 0.52``, SCARA #2 at (0.75, 0, 0) with ``L_base = 0.38``), the bar its bar (0.35 x 0.02 x 0.02 m,
0.15 kg). Both clamps point down; SCARA #1 grips GRIP1 along the bar's own x axis from its centre, #2 GRIP2.
"""
from __future__ import annotations

import math

import numpy as np

DEG = math.pi / 180.0

GRIP1 = 0.10             # SCARA #1's grip along the bar's x axis from its centre (m)
GRIP2 = -0.10            # SCARA #2's

#: the bar's pose on the start stands and on the end stands: centre x, y, z (m), yaw (rad). Between them the
#: bar moves 0.12 m in x and 0.10 m in y (so that neither pair of stands stands under the bar's other pose),
#: turns by 20 deg and rises by 0.05 m
START = (0.25, -0.15, 0.15, 165 * DEG)
END = (0.37, -0.05, 0.19, 185 * DEG)
LIFT = 0.05              # the bar rises this far off the start stands before the carry and comes down this far
#                          onto the end stands after it

#: the stands: two under each pose of the bar, STAND_AT m either side of its centre along it, each a box of
#: half extents STAND_HALF (along the bar, across it; its height reaches from the floor to the bar's underside)
STAND_AT = 0.04
STAND_HALF = (0.015, 0.02)
STAND_FRICTION = 0.8

#: seeded variation of the start: the start stands (and the bar on them) shifted by up to these in x and y (m)
#: and turned by up to this about the vertical (rad), uniformly
START_SHIFT = 0.01
START_TURN = 3 * DEG

# ---- the clamps ----
OPEN = 0.035             # jaw opening while approaching and leaving (m)
FIXED_GAP = 0.001        # the fixed jaw's gap to the bar's side when the clamp arrives (m)
CLOSE_SPEED = 0.02       # mean closing speed of the moving jaw near the bar (m/s)
SQUEEZE = 0.012          # jaw reference while holding: the jaw stop holds it at the bar's width
CLEAR_ABOVE = 0.06       # the clamps arrive from and leave to this far above their grips (m)
#: elbow branch (sign of theta2; for SCARA #2 theta2 = theta3) of each robot throughout, and the turn of each
#: clamp about its approach relative to the bar (0: tool x along the bar's +x, pi: along its -x). The same turn
#: for both puts both moving jaws on the same side of the bar: closing, they shift it sideways by the fixed
#: jaws' gap instead of turning it (opposite sides turned it by 7-9 mrad)
BRANCH = (+1, +1)
FLIP = (math.pi, math.pi)

#: durations (s) of the steps: the approach (down from CLEAR_ABOVE), the grasp (jaws fast to 2 mm over the
#: bar's width, slowly on to SQUEEZE, then settling), lift, carry, place (down onto the end stands), release
#: (jaws open, the welds fade out) and back off (up CLEAR_ABOVE)
TIMES = dict(start=0.2, approach=0.8, close=0.2, grasp_settle=0.3, lift=0.6, carry=2.4, place=0.6, open=0.2,
             release_settle=0.3, back_off=0.6, end_settle=0.4)
KNOTS = dict(approach=6, lift=6, carry=24, place=6, back_off=6)   # straight-line poses between the ends

# ---- success ----
PLACE_TOL = 0.005        # the bar at rest on the end stands within this of its planned pose (m) ...
PLACE_TOL_ANGLE = 0.05   # ... and this (rad)
BACKED_OFF = 0.025       # after backing off, every box of both robots at least this far from the bar (m)
MIN_CLEARANCE = 0.05     # the planned motions keep the two robots' boxes this far apart (m), and
JAW_STAND_CLEARANCE = 0.01  # the jaws this far from every stand, the bar held or not (m)

# ---- control ----
#: gains of the computed-torque baseline: omega (rad/s) per joint, kp = omega^2, kd = 2 omega (the wrist and
#: jaw joints higher, as in the handover)
OMEGA = (np.array([30.0, 30.0, 30.0, 60.0, 60.0, 60.0]), np.array([30.0, 30.0, 30.0, 30.0, 60.0, 60.0]))
#: gains of object-level control (``object``, :class:`coopsim.ObjectControl`): the bar's pose error
#: a* = a_ref + kd e_rate + kp e (kp 1/s^2, kd 1/s: omega 50 rad/s, critically damped; at ObjectControl's
#: default 400 and 40 a bar mass wrong by -50 % in the model left the bar 10 mm RMS off its path), the clamps'
#: wrenches closed on their sensors with kp_force and ki_force (1/s), the integral bounded by integral_limit
#: (N, N m). ki_force 5 (the engine's default 10): the integral drives each clamp's wrench to the one the
#: model commands, so a wrong model mass moves the bar (-50 %: 1.4 mm RMS off its path at 5, 2.0 mm at 10,
#: 0.6 mm at 0), while without it a commanded load share is not met (0.3 commanded: 0.29 at 5, 0.196 at 0)
OBJECT_GAINS = dict(kp=2500.0, kd=100.0, kp_force=0.5, ki_force=5.0, integral_limit=50.0)
#: leader-follower (``leader-follower``, :class:`coopsim.LeaderFollower`): SCARA #1 leads on its own reference,
#: a* = a_ref + kd e_rate + kp e (the engine's defaults kp 900 1/s^2, kd 60 1/s: omega 30 rad/s, critically
#: damped, as the baseline's arm joints); SCARA #2 follows as an impedance over x, y, z, yaw (the directions both
#: SCARAs command) around where the grips put it: stiffness 2000 N/m and 20 N m/rad, mass 1 kg and
#: 0.01 kg m^2, damping 90 N s/m and 0.9 N m s/rad (omega 45 rad/s, damping ratio 1.0 on every axis). At
#: 2000 N/m the follower yields 0.2 mm to the 0.37 N a model mass wrong by 50 % leaves over; stiffer, the
#: default carry's bar error moves by under 0.01 mm up to 2e5 N/m, and with these damping and mass the follower
#: rings against the bar from 2.5e5 N/m (docs/carry.md). follower_share 0.5: the follower carries half of the
#: model's weight of the bar
LEADER_FOLLOWER = dict(stiffness=(2000.0, 2000.0, 2000.0, 20.0), damping=(90.0, 90.0, 90.0, 0.9),
                       mass=(1.0, 1.0, 1.0, 0.01), kp=900.0, kd=60.0, follower_share=0.5)
#: object impedance (``object-impedance``, :class:`coopsim.ObjectControl` with ``impedance``): object-level control
#: as ``object`` (OBJECT_GAINS: the motion loop at omega 50 rad/s) whose bar yields to a push as a
#: mass-spring-damper around its planned path, over x, y, z, rx, ry, rz (world): stiffness 300 N/m, mass 1 kg,
#: damping 24 N s/m (omega 17.3 rad/s, damping ratio 0.69, about 3 times slower than the motion loop; the
#: carry's 2 N push moves the bar F/K = 6.7 mm, and at 17.3 rad/s a step of it is there within its 0.2 s). The
#: rotations scaled by the grips' distance from the bar's centre, r = 0.10 m: stiffness 300 r^2 = 3 N m/rad,
#: mass 1 r^2 = 0.01 kg m^2, damping 0.24 N m s/rad (the same omega and damping ratio; a force at a grip sees the
#: same stiffness turning the bar as moving it). The bar's weight in the model is part of the push's estimate: a
#: model mass wrong by +-50 % moves the bar 0.5 * 0.15 kg * 9.81 m/s^2 / 300 N/m = 2.5 mm up or down.
#: accel_filter 0.01 s (the engine's default 0.002): the time constant of the filter on the bar's measured
#: acceleration in the push's estimate. Shorter, the estimate rings at the controllers' half rate (500 Hz) in
#: the carry, tens of N through the clamps: at 0 s a clamp slips out; from 0.001 to 0.004 s it rings in some
#: runs (with the model mass +50 % at 0.004 s a jaw then meets a stand); from 0.006 s it is quiet (0.01 N)
OBJECT_IMPEDANCE = dict(stiffness=(300.0, 300.0, 300.0, 3.0, 3.0, 3.0), damping=(24.0, 24.0, 24.0, 0.24, 0.24, 0.24),
                        mass=(1.0, 1.0, 1.0, 0.01, 0.01, 0.01), accel_filter=0.01)
