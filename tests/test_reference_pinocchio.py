"""An independent reference: Pinocchio's CRBA, RNEA and ABA on the robot
loaded from our URDF export must equal coopsim's M, inverse and forward
dynamics (friction aside, which URDF only records as joint damping)."""
from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest

import coopsim as cs
from conftest import random_robot

pin = pytest.importorskip("pinocchio", reason="Pinocchio ('pin' on PyPI) is installed by the test extra")


def load(robot):
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(robot.to_urdf())
    try:
        return pin.buildModelFromUrdf(f.name)
    finally:
        os.unlink(f.name)


def limited(seed, dof):
    r = random_robot(seed, dof=dof)
    # finite limits make every revolute joint 'revolute' (nq = 1) in URDF
    return cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, r.joint_types, friction=r.friction_coefficients,
                            q_limits=np.tile([-4.0, 4.0], (dof, 1)), base_position=r.base_position,
                            base_yaw=r.base_yaw, name=r.name)


ROBOTS = [cs.robots.scara1(backend="numeric"), cs.robots.scara2(backend="numeric"), cs.robots.scara1(),
          cs.robots.scara2()] + [limited(300 + s, 6) for s in range(6)] + [limited(400, 3), limited(401, 9)]


@pytest.mark.parametrize("robot", ROBOTS, ids=[f"{r.name}-{r.backend}" for r in ROBOTS])
def test_dynamics_equal_pinocchio(robot):
    model = load(robot)
    data = model.createData()
    assert model.nq == robot.dof
    rng = np.random.default_rng(5)
    lim = robot.q_limits
    for _ in range(20):
        q = rng.uniform(np.maximum(lim[:, 0], -3), np.minimum(lim[:, 1], 3))
        qd, qdd, tau = rng.normal(size=robot.dof), rng.normal(size=robot.dof), rng.normal(size=robot.dof)
        M_pin = pin.crba(model, data, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        M = robot.mass_matrix(q)
        np.testing.assert_allclose(M, M_pin, rtol=0, atol=1e-12 * max(1.0, np.abs(M).max()))
        tau_pin = pin.rnea(model, data, q, qd, qdd)
        tau_ours = robot.inverse_dynamics(q, qd, qdd) - robot.friction(qd)
        np.testing.assert_allclose(tau_ours, tau_pin, rtol=0, atol=1e-11 * max(1.0, np.abs(tau_pin).max()))
        qdd_pin = pin.aba(model, data, q, qd, tau)
        qdd_ours = robot.forward_dynamics(q, qd, tau + robot.friction(qd))
        np.testing.assert_allclose(qdd_ours, qdd_pin, rtol=1e-9, atol=1e-9)
        # frames: the tip of the chain
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        flange = data.oMf[model.getFrameId("flange")].homogeneous
        np.testing.assert_allclose(flange, robot.frames(q)[-1], atol=1e-12)
