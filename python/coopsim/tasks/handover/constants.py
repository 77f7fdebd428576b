"""The handover's planning values (m, rad, s), checked against the robots' kinematics in tests/test_task.py."""
from __future__ import annotations

import math

import numpy as np

DEG = math.pi / 180.0

#: Region of randomised bar starts: centre x, y (m) and yaw (rad), all pickable by SCARA #2.
REGION = dict(x=(0.90, 1.00), y=(0.25, 0.35), yaw=(15 * DEG, 45 * DEG))

# ---- planning values (m, rad, s) ----
HANDOVER_CENTRE = np.array([0.25, 0.25, 0.20])
HANDOVER_YAW = 285 * DEG
GRIP1 = -0.075           # #1's grip along the bar from its centre (the bar's +x end enters the tube first)
GRIP2 = 0.125            # #2's grip along the bar from its centre
PICK_HEIGHT = 0.015      # #2's tool centre point above the bar's centre at pick-up
OPEN = 0.035             # jaw opening while approaching a bar (m)
FIXED_GAP = 0.001        # the fixed jaw's gap to the bar when the clamp arrives (m)
CLOSE_SPEED = 0.02       # mean closing speed of the jaw near the bar (m/s)
SQUEEZE = 0.012          # jaw reference while closing: the jaw stop holds it at the bar's width
CLEAR_ABOVE = 0.08       # height of the approach / retreat above a grip
INSERT_PITCH = 65 * DEG  # #1's clamp pitch theta5 during insertion
BESIDE = 0.10            # #1 arrives this far beside the container's axis (horizontally, towards +x)
BEFORE_MOUTH = 0.03      # the bar's leading end stops this far before the mouth before it goes in
INSERT_DEPTH = 0.20      # how far the leading end goes into the tube
RETREAT2 = 0.04          # #2 rises this far off the bar after letting go (its quill stroke then stays above
                         # 0.03 m, where its clamp body clears its own forearm)
BACK_OFF = 0.06          # #1 backs off along its approach after opening
SLIDE_MIN = 0.05         # a released bar must slide at least this far down the tube's axis (m)
RELEASE_FADE = 0.1       # s: the weld fades out over this after the jaw opens (the simulation's release_time)
SLIDE_BACK = 0.02        # ... and never move back up it faster than this (m/s)
LINE_SPACING = 0.07      # bars lined up for repeated cycles, centre to centre
#: the most cycles the scene takes: the first two bars slide out of the tube's lower mouth and come to rest on
#: the floor just below it, the second lying across the exit, so the third stops inside the tube (its centre
#: 0.25 m down the 0.40 m tube) and a fourth bar, pushed in, hits it (a forbidden contact in its insertion)
MAX_CYCLES = 3

# durations of the motions (s)
TIMES = dict(approach=1.5, descend=0.6, close=0.2, lift=0.6, carry=2.4, enter=0.8, open=0.2, retreat=0.5,
             home=1.2, to_container=2.4, slide_on=0.6, insert=1.2, back_off=0.5, settle=0.3)
GRASP_TIMEOUT = 1.0      # s for a grasp or a release to happen once the jaws are commanded

#: elbow branches (sign of theta2) of SCARA #1 and #2 throughout: #1's elbow out to the left keeps its
#: forearm clear of #2's quill at the handover; #2's the other way
BRANCH = (-1, +1)
#: SCARA #1's elbow branch for the insertion (the only one that reaches along the container's axis): it
#: turns its elbow over on the way from the handover
INSERT_BRANCH = +1

# gains of the computed-torque controllers: omega (rad/s) per joint
#: (the wrist joints higher: a held bar multiplies their inertia, which the controllers' models leave out)
OMEGA = (np.array([30.0, 30.0, 30.0, 60.0, 60.0, 60.0]), np.array([30.0, 30.0, 30.0, 30.0, 60.0, 60.0]))
