"""The Gymnasium environments (coopsim.envs): Gymnasium's checks, seeds repeating episodes bit for bit, the
vector environment against the single ones, refused actions, resets after a failure, rewards one arm
cannot collect alone, the cooperative law's commands set during a run, and the dual carry with one
PettingZoo agent per arm."""
import subprocess
import sys

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import coopsim  # noqa: E402
import coopsim.envs  # noqa: E402,F401  (registers the environments)
from coopsim.envs import DualCarryEnv, HandoverEnv, ReachEnv  # noqa: E402
import coopsim.tasks.handover  # noqa: E402,F401
from gymnasium.utils.env_checker import check_env  # noqa: E402
from gymnasium.vector import AutoresetMode  # noqa: E402
from gymnasium.wrappers import FlattenObservation  # noqa: E402


def _episode(env, seed, actions, options=None):
    """Observations, rewards, terminated and truncated flags of one episode of `actions` (a function of the
    step number and the observation, or a fixed action) from reset(seed=seed)."""
    obs, info = env.reset(seed=seed, options=options)
    out = dict(obs=[obs], rewards=[], done=[], infos=[info])
    k = 0
    while True:
        a = actions(k, obs) if callable(actions) else actions
        obs, r, term, trunc, info = env.step(a)
        out["obs"].append(obs)
        out["rewards"].append(r)
        out["done"].append((term, trunc))
        out["infos"].append(info)
        k += 1
        if term or trunc:
            return out


def _flat(obs):
    if isinstance(obs, dict):
        return np.concatenate([np.ravel(obs[k]) for k in sorted(obs)])
    return np.ravel(obs)


def _same(a, b):
    assert len(a["obs"]) == len(b["obs"])
    for x, y in zip(a["obs"], b["obs"]):
        np.testing.assert_array_equal(_flat(x), _flat(y))
    assert a["rewards"] == b["rewards"]
    assert a["done"] == b["done"]


#: the scripted carry's commands
SCRIPTED_CARRY = np.array([0.0, 0.0, 0.0, 0.0, 0.5])


def _seeded_torques(env, seed, scale=0.3):
    rng = np.random.default_rng(seed)
    high = env.action_space.high
    return lambda k, obs: scale * high * rng.uniform(-1.0, 1.0, high.shape)


def _gentle(k, obs):
    """A carry policy that moves the commands a little and smoothly: the offset a few mm, the squeeze and the
    load share around the scripted ones."""
    s = np.sin(0.1 * k)
    return np.array([0.002 * s, -0.001 * s, 0.002 * s, 0.5 + 0.5 * s, 0.5 + 0.05 * s])


# ---- packaging ----

def test_coopsim_imports_without_gymnasium_and_envs_says_what_is_missing():
    code = ("import sys; sys.modules['gymnasium'] = None\n"
            "import coopsim, coopsim.tasks.carry\n"
            "assert 'coopsim.envs' not in sys.modules\n"
            "try:\n    import coopsim.envs\nexcept ImportError as e:\n    print('refused:', e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "refused:" in out.stdout and "gymnasium" in out.stdout


def test_the_gym_extra_is_declared_installed_by_setup_and_in_the_test_extra():
    import os
    import re

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with open(os.path.join(root, "pyproject.toml"), encoding="utf-8") as f:
        toml = f.read()
    gym_extra = re.search(r"^gym = \[(.*?)\]", toml, flags=re.M).group(1)
    test_extra = re.search(r"^test = \[(.*?)\]\s*(#[^\n]*)?\n\S", toml, flags=re.M | re.S).group(1)
    for req in ('"gymnasium>=1.0"', '"pettingzoo>=1.24"'):
        assert req in gym_extra and req in test_extra
    with open(os.path.join(root, "scripts", "setup.sh"), encoding="utf-8") as f:
        extras = re.search(r'pip install -q --no-build-isolation "\.\[([a-z,]+)\]"', f.read()).group(1).split(",")
    assert "gym" in extras


def test_the_environments_are_registered_under_their_ids_and_by_module_path():
    for env_id, cls in (("coopsim/Reach-v0", ReachEnv), ("coopsim/DualCarry-v0", DualCarryEnv)):
        assert env_id in gym.registry
        env = gym.make(env_id)
        assert isinstance(env.unwrapped, cls)
        env.close()
    env = gym.make("coopsim.envs:coopsim/Reach-v0", action="setpoint")
    assert env.unwrapped.mode == "setpoint"
    env.close()


# ---- Gymnasium's checks ----

# the actions are in SI units (N m, m, N), not Gymnasium's advised [-1, 1]: that advice alone is let pass
# (gymnasium.wrappers.RescaleAction gives the normalised space, docs/envs.md)
@pytest.mark.filterwarnings("ignore:.*symmetric and normalized space:UserWarning")
@pytest.mark.parametrize("make", [lambda: ReachEnv(), lambda: ReachEnv(action="setpoint"),
                                  lambda: DualCarryEnv()], ids=["reach-torque", "reach-setpoint", "carry"])
def test_check_env_passes(make):
    env = make()
    check_env(env, skip_render_check=True)
    env.close()


def test_render_gives_rgb_frames_of_the_scene():
    for env in (ReachEnv(render_mode="rgb_array"), DualCarryEnv(render_mode="rgb_array")):
        env.reset(seed=2)
        env.step(env.action_space.sample() * 0.0 + getattr(env, "scripted_action", 0.0))
        frame = env.render()
        assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
        assert frame.shape[:2] == (360, 480)
        assert np.unique(frame.reshape(-1, 3), axis=0).shape[0] > 50      # a drawing, not a blank canvas
        env.close()


def test_the_carry_observation_flattens():
    env = FlattenObservation(DualCarryEnv())
    obs, _ = env.reset(seed=1)
    assert obs.shape == env.observation_space.shape and obs.ndim == 1
    obs, *_ = env.step(env.unwrapped.scripted_action)
    assert env.observation_space.contains(obs)


# ---- the tasks ----

def test_reach_setpoints_towards_the_target_reach_it_and_end_the_episode():
    env = ReachEnv(action="setpoint")
    ep = _episode(env, 0, lambda k, obs: np.clip(obs[-3:], -env.max_offset, env.max_offset))
    last = ep["infos"][-1]
    assert ep["done"][-1] == (True, False) and last["success"]
    assert last["distance"] < env.tolerance and last["speed"] < env.max_speed
    assert ep["rewards"][-1] > ep["rewards"][0]


def test_reach_truncates_at_its_time_limit():
    env = ReachEnv(time_limit=0.2)
    ep = _episode(env, 1, np.zeros(6))
    assert len(ep["rewards"]) == 10 and ep["done"][-1] == (False, True)
    assert ep["infos"][-1]["time"] == pytest.approx(0.2)


def test_reach_targets_are_drawn_by_the_seed_within_reach():
    env = ReachEnv()
    targets = np.array([env.reset(seed=s)[0][-6:-3] for s in range(50)])
    assert len({tuple(t) for t in targets}) == 50
    np.testing.assert_array_equal(env.reset(seed=3)[0], env.reset(seed=3)[0])
    lo, hi = env.robot.q_limits[:, 0], env.robot.q_limits[:, 1]
    for seed, t in enumerate(targets):   # each the TCP of a configuration drawn within the limits by the seed
        rng, _ = gym.utils.seeding.np_random(seed)
        q = rng.uniform(lo, hi)
        q[3:] = coopsim.envs.reach.Q0[3:]
        assert np.all((q >= lo) & (q <= hi))
        np.testing.assert_array_equal(env.robot.fk(q)[:3, 3], t)


def test_the_scripted_carry_succeeds_and_a_one_arm_carry_earns_less_than_half():
    env = DualCarryEnv()
    two = _episode(env, 3, env.scripted_action)
    assert two["done"][-1] == (True, False) and two["infos"][-1]["success"], two["infos"][-1].get("failure")
    assert len(two["rewards"]) == 180          # 3.6 s of lift, carry and place at 50 Hz
    one = _episode(env, 3, np.array([0.0, 0.0, 0.0, 0.0, 1.0]))   # SCARA #1 carries the whole bar
    assert sum(one["rewards"]) < 0.5 * sum(two["rewards"])
    terms = one["infos"][90]["reward_terms"]
    assert terms["share"][1] < 0.2 and one["infos"][90]["reward_terms"]["task"].min() > 0.5
    tense = _episode(env, 3, np.array([0.0, 0.0, 0.0, 3.0, 0.5]))  # squeezing the bar (3 N, the most allowed)
    assert sum(tense["rewards"]) < sum(two["rewards"])


def test_an_offset_moves_the_bar_off_its_plan_by_it():
    env = DualCarryEnv()
    obs, _ = env.reset(seed=1)
    for _ in range(40):
        obs, r, term, trunc, info = env.step(np.array([0.0, 0.0, 0.01, 0.0, 0.5]))
    assert not term
    assert obs["bar_error"][2] == pytest.approx(-0.01, abs=1.5e-3)     # the plan less the bar: 1 cm up
    assert np.all(np.abs(obs["bar_error"][:2]) < 2e-3)


def test_a_heavier_bar_is_carried_by_the_same_commands():
    env = DualCarryEnv(bar_mass=0.3)
    ep = _episode(env, 4, env.scripted_action)
    assert ep["infos"][-1]["bar_mass"] == 0.3 and ep["infos"][-1]["success"]
    light = _episode(env, 4, env.scripted_action, options={"bar_mass": 0.1})
    assert light["infos"][-1]["bar_mass"] == 0.1
    up = [np.sum(o["wrench"][:, 2]) for o in (ep["obs"][60], light["obs"][60])]
    assert up[0] == pytest.approx(0.3 * 9.81, rel=0.15) and up[1] == pytest.approx(0.1 * 9.81, rel=0.15)


def _rotation(quaternion):
    w, x, y, z = quaternion
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def test_the_pair_readout_is_what_the_separate_calls_read():
    """Simulation.pair_readout (one engine call per step of the carry) against the dozen calls it replaces,
    during a hold and after a clamp let go (the pair's part zeros then), for two simulations at once."""
    envs = [DualCarryEnv(), DualCarryEnv()]
    for i, env in enumerate(envs):
        env.reset(seed=5 + i)
        for k in range(30):
            env.step(_gentle(k, None))
    envs[1].sim.release(1)
    rows = coopsim.Simulation.pair_readout([e.sim for e in envs], 0, 1, "bar")
    assert rows.shape == (2, 96) and rows.dtype == np.float64
    for env, row in zip(envs, rows):
        sim, robots = env.sim, env.plan.robots
        together = sim.holding(0) == "bar" and sim.holding(1) == "bar"
        c = sim.cooperation(0, 1)
        assert row[0] == sim.time and row[1] == float(together) == float(c.holding)
        assert list(row[2:4]) == [float(sim.holding(i) == "bar") for i in range(2)]
        assert row[4] == len(sim.contact_events()["a"]) and row[5] == len(sim.grasp_events()["t"])
        for i, at in enumerate((6, 37)):
            q, qd = sim.state(i)
            T = robots[i].fk(q)
            np.testing.assert_array_equal(row[at:at + 12], np.r_[q, qd])
            np.testing.assert_allclose(row[at + 12:at + 15], T[:3, 3], atol=1e-12)
            assert row[at + 15] >= 0.0
            np.testing.assert_allclose(_rotation(row[at + 15:at + 19]), T[:3, :3], atol=1e-7)
            np.testing.assert_allclose(row[at + 19:at + 25], robots[i].tool_jacobian(q) @ qd, atol=1e-12)
            np.testing.assert_array_equal(row[at + 25:at + 31], sim.sensor(i).ft_world)
        b = sim.body_state("bar")
        np.testing.assert_array_equal(row[68:71], b.pose[:3, 3])
        np.testing.assert_allclose(_rotation(row[71:75]), b.pose[:3, :3], atol=1e-7)
        np.testing.assert_array_equal(row[75:81], np.r_[b.velocity, b.angular_velocity])
        pair = np.r_[c.internal, c.squeeze, c.load_share] if together else np.zeros(15)
        np.testing.assert_array_equal(row[81:96], pair)
    assert rows[0, 1] == 1.0 and rows[1, 1] == 0.0 and np.all(rows[1, 81:] == 0.0)
    for args, match in ((("bar", 1, 0), "a"), (("bar", 0, 2), "b"), (("stand", 0, 1), "stand")):
        body, a, b = args
        with pytest.raises(ValueError, match=match):
            coopsim.Simulation.pair_readout([envs[0].sim], a, b, body)
    with pytest.raises(ValueError, match="world"):
        coopsim.Simulation.pair_readout([coopsim.Simulation()], 0, 1, "bar")


def test_the_engine_pool_advances_and_reads_chunks_as_advance_all_and_pair_readout_do():
    """Simulation.advance_pool (the vector environment's pipeline): chunks handed to its engine threads one
    after the other, each simulation to its own end time and then read, give what advance_all and
    pair_readout give the same simulations one chunk at a time, bit for bit; bad chunks are named."""
    def started(seeds):
        envs = [DualCarryEnv() for _ in seeds]
        for env, seed in zip(envs, seeds):
            env.reset(seed=seed)
        return envs
    seeds = (3, 4, 5, 6)
    a, b = started(seeds), started(seeds)
    pool = coopsim.Simulation.advance_pool(2)
    assert pool.threads == 2
    ends = [e.sim.time + dt for e, dt in zip(a, (0.02, 0.04, 0.02, 0.06))]
    jobs = [pool.submit([a[0].sim, a[1].sim], ends[:2], (0, 1, "bar")),
            pool.submit([a[2].sim, a[3].sim], ends[2:], (0, 1, "bar"))]
    got = [job.result() for job in jobs]
    got.append(pool.submit([a[3].sim], [ends[3] + 0.01]).result())     # a second leg, no readout
    for k, (chunk, t_end) in enumerate((([b[0], b[1]], ends[:2]), ([b[2], b[3]], ends[2:]))):
        for env, t in zip(chunk, t_end):
            assert coopsim.Simulation.advance_all([env.sim], t) == [None]
        errors, rows = got[k]
        assert errors == [None, None]
        np.testing.assert_array_equal(rows, coopsim.Simulation.pair_readout([e.sim for e in chunk], 0, 1, "bar"))
    assert got[2][0] == [None] and got[2][1] is None
    coopsim.Simulation.advance_all([b[3].sim], ends[3] + 0.01)
    for x, y in zip(a, b):
        assert x.sim.time == y.sim.time
        for i in range(2):
            for u, v in zip(x.sim.state(i), y.sim.state(i)):
                np.testing.assert_array_equal(u, v)
    assert a[0].sim.stats.sim_elapsed == pytest.approx(0.02) and a[0].sim.stats.steps == 100
    # the caller helping its pool: run_one runs the chunk queued first on the caller's thread (True) until none
    # is queued (False); done() tells without waiting; the same states and rows as advance_all's
    c, d = started(seeds[:3]), started(seeds[:3])
    solo = coopsim.Simulation.advance_pool(1)
    ends = [e.sim.time + 0.02 for e in c]
    jobs = [solo.submit([e.sim], [t], (0, 1, "bar")) for e, t in zip(c, ends)]
    helped = 0
    while solo.run_one():
        helped += 1
    assert 0 <= helped <= 3 and solo.run_one() is False
    got = [job.result() for job in jobs]
    assert all(job.done() for job in jobs)
    for e, t, (errors, rows) in zip(d, ends, got):
        assert coopsim.Simulation.advance_all([e.sim], t) == [None] and errors == [None]
        np.testing.assert_array_equal(rows, coopsim.Simulation.pair_readout([e.sim], 0, 1, "bar"))
    for x, y in zip(c, d):
        for i in range(2):
            for u, v in zip(x.sim.state(i), y.sim.state(i)):
                np.testing.assert_array_equal(u, v)
    with pytest.raises(ValueError, match="t_end"):
        pool.submit([a[0].sim, a[1].sim], [1.0])
    with pytest.raises(ValueError, match="t_end"):
        pool.submit([a[0].sim], [float("nan")])
    with pytest.raises(ValueError, match="same simulation"):
        pool.submit([a[0].sim, a[0].sim], [5.0, 5.0]).result()
    with pytest.raises(ValueError, match="stand"):
        pool.submit([a[1].sim], [a[1].sim.time], (0, 1, "stand")).result()
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="threads"):
            coopsim.Simulation.advance_pool(bad)


def test_the_carry_observation_is_the_simulation_s_state_and_the_plan_s_error():
    env = DualCarryEnv()
    env.reset(seed=2)
    for k in range(50):
        obs, *_ = env.step(_gentle(k, None))
    sim, plan = env.sim, env.plan
    for i in range(2):
        q, qd = sim.state(i)
        T = plan.robots[i].fk(q)
        np.testing.assert_array_equal(obs["q"][i], q)
        np.testing.assert_allclose(obs["clamp_pose"][i][:3], T[:3, 3], atol=1e-12)
        np.testing.assert_allclose(_rotation(obs["clamp_pose"][i][3:]), T[:3, :3], atol=1e-7)
    B, P = sim.body_state("bar").pose, plan.bar.pose(sim.time)
    np.testing.assert_allclose(obs["bar_error"][:3], P[:3, 3] - B[:3, 3], atol=1e-12)
    R = P[:3, :3] @ B[:3, :3].T                       # the plan's rotation times the bar's transposed
    angle = np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2.0 * np.sin(angle))
    np.testing.assert_allclose(obs["bar_error"][3:], angle * axis, atol=1e-7)
    assert 0.0 < obs["phase"][0] < 1.0 and obs["phase"][0] == pytest.approx((sim.time - env.t0) / (env.t_end - env.t0))


# ---- seeds ----

def test_the_same_seed_gives_the_same_episode_bit_for_bit():
    for make, actions in ((lambda: ReachEnv(time_limit=0.5), None), (lambda: DualCarryEnv(), _gentle)):
        a, b = make(), make()
        pol = [actions or _seeded_torques(a, 9), actions or _seeded_torques(b, 9)]
        _same(_episode(a, 11, pol[0]), _episode(b, 11, pol[1]))
        c = make()
        other = _episode(c, 12, actions or _seeded_torques(c, 9))
        assert not np.array_equal(_flat(other["obs"][0]), _flat(_episode(a, 11, pol[0])["obs"][0]))


# ---- bad actions ----

@pytest.mark.parametrize("make", [ReachEnv, DualCarryEnv], ids=["reach", "carry"])
def test_bad_actions_are_refused_in_one_line_naming_the_action(make):
    env = make()
    env.reset(seed=0)
    n = env.action_space.shape[0]
    good = np.clip(np.zeros(n), env.action_space.low, env.action_space.high)
    nan = good.copy()
    nan[0] = np.nan
    out = good.copy()
    out[-1] = env.action_space.high[-1] * 2.0 + 1.0
    for bad, words in ((nan, "finite"), (np.zeros(n + 1), "shape"), (out, "bounds"), ("left", "numbers")):
        with pytest.raises(ValueError, match=words) as e:
            env.step(bad)
        msg = str(e.value)
        assert msg.startswith("action ") and "\n" not in msg
    obs, r, term, trunc, info = env.step(good)           # nothing was applied: the episode goes on
    assert not term and info["time"] > 0


def test_the_vector_environment_refuses_a_bad_action_before_applying_any():
    v = gym.make_vec("coopsim/Reach-v0", num_envs=2, vectorization_mode="vector_entry_point")
    v.reset(seed=0)
    acts = np.zeros((2, 6))
    acts[1, 2] = np.inf
    with pytest.raises(ValueError, match=r"^actions\[1\] must be finite"):
        v.step(acts)
    assert all(s.time == 0.0 for s in v.unwrapped.sims)
    v.close()


# ---- failures and resets ----

def test_an_episode_after_a_failure_resets_cleanly():
    env = DualCarryEnv(max_offset=0.05)   # offsets of 5 cm (default 1 cm): random ones pull a clamp off
    env.reset(seed=5)
    env.action_space.seed(5)
    for k in range(180):                               # random commands: the offset jumps by cm a step
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        if term:
            break
    assert term and "failure" in info and r == 0.0
    assert info["failure"]["step"] in ("lift", "carry", "place") and info["failure"]["reason"]
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.scripted_action)
    _same(_episode(env, 6, _gentle), _episode(DualCarryEnv(), 6, _gentle))


def test_a_start_that_fails_ends_the_episode_at_its_first_step():
    env = DualCarryEnv(bar_mass=2.0)          # too heavy: the grasp step fails, scripted
    obs, info = env.reset(seed=1)
    assert info["failure"]["step"] == "grasp" and info["failure"]["reason"]
    obs2, r, term, trunc, info2 = env.step(env.scripted_action)
    assert (r, term, trunc) == (0.0, True, False) and info2["failure"] == info["failure"]
    np.testing.assert_array_equal(_flat(obs2), _flat(obs))          # nothing advanced
    ok = _episode(env, 1, env.scripted_action, options={"bar_mass": 0.15})
    assert ok["infos"][-1]["success"]
    v = gym.make_vec("coopsim/DualCarry-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     bar_mass=[0.15, 2.0])
    v.reset(seed=[1, 1])
    _, r, term, _, info = v.step(np.tile(env.scripted_action, (2, 1)))
    assert list(term) == [False, True] and r[1] == 0.0 and r[0] > 0.5 and info["failure"]["step"][1] == "grasp"
    v.close()


# ---- the vector environment ----

def _vector_episodes(env_id, n, seeds, actions, steps, threads=2, **kwargs):
    v = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", threads=threads, **kwargs)
    obs, _ = v.reset(seed=seeds)
    out = [obs]
    rewards, dones, infos = [], [], []
    for k in range(steps):
        obs, r, term, trunc, info = v.step(np.stack([actions(i, k) for i in range(n)]))
        out.append(obs)
        rewards.append(r)
        dones.append((term, trunc))
        infos.append(info)
    v.close()
    return out, rewards, dones, infos


def _obs_i(obs, i):
    return {k: v[i] for k, v in obs.items()} if isinstance(obs, dict) else obs[i]


@pytest.mark.parametrize("threads", [1, 2], ids=["one-thread", "two-halves-pipelined"])
@pytest.mark.parametrize("limits", [[0.2, 0.3, 0.5], [0.2, 0.2, 0.2]], ids=["out-of-step", "together"])
def test_vector_reach_equals_the_single_environments_with_autoresets(threads, limits):
    """On one thread the step runs every environment in turn; on more, its two halves in a pipeline (one half's
    engine call while Python applies or reads the other) and the resets of one step side by side on the pool:
    the same episodes either way. limits: episodes of 10, 15 and 25 steps (resets out of step), or of 10 each
    (all three reset in the same step)."""
    n, steps, seeds = 3, 24, [4, 7, 9]
    rngs = [np.random.default_rng(100 + i) for i in range(n)]
    high = ReachEnv().action_space.high
    acts = [[0.3 * high * rngs[i].uniform(-1, 1, 6) for _ in range(steps)] for i in range(n)]
    obs, rewards, dones, _ = _vector_episodes("coopsim/Reach-v0", n, seeds, lambda i, k: acts[i][k], steps,
                                              threads=threads, time_limit=limits)
    for i in range(n):
        env = ReachEnv(time_limit=limits[i])
        o, _ = env.reset(seed=seeds[i])
        np.testing.assert_array_equal(obs[0][i], o)
        reset_next = False
        for k in range(steps):
            if reset_next:                           # NEXT_STEP: this step resets, its action unused
                o, _ = env.reset()
                r, term, trunc = 0.0, False, False
            else:
                o, r, term, trunc, _ = env.step(acts[i][k])
            np.testing.assert_array_equal(obs[k + 1][i], o)
            assert rewards[k][i] == r and (dones[k][0][i], dones[k][1][i]) == (term, trunc)
            reset_next = term or trunc
    assert any(d[1][0] for d in dones) and any(d[1][1] for d in dones)


def test_vector_carry_equals_the_single_environments_with_a_bar_mass_each():
    n, steps, seeds, masses = 2, 30, [1, 2], [0.12, 0.2]
    obs, rewards, dones, infos = _vector_episodes("coopsim/DualCarry-v0", n, seeds, lambda i, k: _gentle(k + i, None),
                                                  steps, bar_mass=masses)
    np.testing.assert_array_equal(infos[-1]["bar_mass"], masses)
    for i in range(n):
        env = DualCarryEnv(bar_mass=masses[i])
        o, _ = env.reset(seed=seeds[i])
        np.testing.assert_array_equal(_flat(_obs_i(obs[0], i)), _flat(o))
        for k in range(steps):
            o, r, term, trunc, _ = env.step(_gentle(k + i, None))
            np.testing.assert_array_equal(_flat(_obs_i(obs[k + 1], i)), _flat(o))
            assert rewards[k][i] == r and not term


def test_vector_carry_resets_side_by_side_as_the_single_environments():
    """Two carries end together at the place (180 steps) and reset in the same step, side by side on the pool
    (each planning and simulating its grasp on a worker thread): the single environments' episodes bit for bit."""
    n, steps, seeds = 2, 184, [1, 2]
    obs, rewards, dones, _ = _vector_episodes("coopsim/DualCarry-v0", n, seeds, lambda i, k: _gentle(k + i, None),
                                              steps)
    assert [bool(d[0].all()) for d in dones].index(True) == 179          # both end at the 180th step
    for i in range(n):
        env = DualCarryEnv()
        o, _ = env.reset(seed=seeds[i])
        np.testing.assert_array_equal(_flat(_obs_i(obs[0], i)), _flat(o))
        reset_next = False
        for k in range(steps):
            if reset_next:                           # NEXT_STEP: this step resets (the next seed of the env)
                o, _ = env.reset()
                r, term = 0.0, False
            else:
                o, r, term, _, _ = env.step(_gentle(k + i, None))
            np.testing.assert_array_equal(_flat(_obs_i(obs[k + 1], i)), _flat(o))
            assert rewards[k][i] == r and dones[k][0][i] == term
            reset_next = term


def test_vector_same_step_autoreset_returns_the_final_observation():
    v = gym.make_vec("coopsim/Reach-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     autoreset_mode=AutoresetMode.SAME_STEP, time_limit=[0.1, 0.2])
    assert v.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    v.reset(seed=[0, 1])
    for k in range(5):
        obs, r, term, trunc, info = v.step(np.zeros((2, 6)))
    assert trunc[0] and not trunc[1]
    assert info["_final_obs"][0] and not info["_final_obs"][1]
    final = info["final_obs"][0]
    assert final[-3:] @ final[-3:] > 0 and not np.array_equal(final, obs[0])
    assert v.unwrapped.sims[0].time == 0.0           # reset in the same step
    v.close()


def _same_info(a, b):
    assert list(a) == list(b)
    for key in a:
        if isinstance(a[key], dict):
            _same_info(a[key], b[key])
            continue
        assert type(a[key]) is type(b[key]) and a[key].dtype == b[key].dtype and a[key].shape == b[key].shape, key
        if a[key].dtype == object:
            assert all(x is y for x, y in zip(a[key], b[key])), key
        else:
            np.testing.assert_array_equal(a[key], b[key])


def test_the_vector_info_is_gymnasium_s_add_info_of_each_environment_in_turn():
    venv = gym.make_vec("coopsim/Reach-v0", num_envs=4, vectorization_mode="vector_entry_point", threads=1)
    obs = {"q": np.ones(3)}
    entries = [(0, dict(time=0.5, step="lift", ok=True, n=3, v=np.arange(3.0), s=np.float32(2.0), start=(1.0, 2.0),
                        terms=dict(a=np.zeros(2), b=1.0), flag=np.bool_(True))),
               (2, dict(final_obs=obs, final_info=dict(time=0.7, failure=dict(reason="let go", t=0.6)))),
               (2, dict(time=1.5, step="carry", ok=False, n=4.0, v=np.ones(3), extra=None, terms=dict(b=2.0))),
               (3, dict(step="place", start=(3.0, 4.0), final_obs=obs))]
    expected: dict = {}
    for i, info in entries:
        expected = venv.unwrapped._add_info(expected, info, i)
    _same_info(venv.unwrapped._gathered(entries), expected)
    _, _, _, _, info = venv.step(venv.action_space.sample())          # a step's info, as _add_info builds it
    assert list(info)[:6] == ["distance", "_distance", "speed", "_speed", "time", "_time"]
    assert info["distance"].shape == (4,) and info["_distance"].all() and info["success"].dtype == np.bool_
    venv.close()


def test_vector_keywords_are_checked():
    with pytest.raises(ValueError, match="bar_mass must be one value or one per environment"):
        gym.make_vec("coopsim/DualCarry-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     bar_mass=[0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="autoreset_mode"):
        gym.make_vec("coopsim/Reach-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     autoreset_mode=AutoresetMode.DISABLED)
    with pytest.raises(ValueError, match="bar_mass must be finite and > 0 kg"):
        DualCarryEnv(bar_mass=-1.0)
    with pytest.raises(ValueError, match="control_rate"):
        ReachEnv(control_rate=0.0)
    with pytest.raises(ValueError, match="action must be .torque. or .setpoint."):
        ReachEnv(action="velocity")


# ---- the live page ----

@pytest.mark.slow
def test_reach_in_human_mode_runs_through_the_live_page():
    pytest.importorskip("viser")
    from test_live import live_page, open_live
    from test_replay import _browser_or_skip, CHROMIUM

    sync_playwright = _browser_or_skip()
    env = ReachEnv(action="setpoint", render_mode="human")
    obs, _ = env.reset(seed=0)
    env.render()                                   # opens the page before the first step
    view = env._live
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=["--use-angle=swiftshader",
                                                               "--enable-unsafe-swiftshader"])
        try:
            open_live(live_page(b, 900, 560), view.url)
            ep = []
            while True:
                obs, r, term, trunc, info = env.step(np.clip(obs[-3:], -0.05, 0.05))
                ep.append(info)
                if term or trunc:
                    break
        finally:
            b.close()
    assert ep[-1]["success"] and view.sim is env.sim and env.sim.time == pytest.approx(ep[-1]["time"])
    # the paced run is the same run as the headless one
    assert [i["distance"] for i in ep] == [i["distance"] for i in
                                          _episode(ReachEnv(action="setpoint"), 0,
                                                   lambda k, o: np.clip(o[-3:], -0.05, 0.05))["infos"][1:]]
    env.close()
    assert env._live is None


# ---- the law's commands set during a run ----

def _law_from_start(env, seed, **built):
    """env reset at `seed` (the bar held under the carry's law), its law replaced by a new one (the carry's,
    with `built` at construction): (env, the new law)."""
    from coopsim.tasks.carry import controllers

    env.reset(seed=seed)
    sim, runner = env.sim, env.runner
    sim.remove_cooperative(runner.group)
    law = controllers.object_control(env.plan.robots, env.plan, **built).law
    return law, lambda: sim.add_cooperative(law, [0, 1])


def test_commands_set_before_the_first_update_equal_a_law_built_with_them():
    a, b = DualCarryEnv(), DualCarryEnv()
    law_a, start_a = _law_from_start(a, 2, squeeze=3.0, load_share=0.3)
    law_b, start_b = _law_from_start(b, 2)
    start_a()
    start_b()
    law_b.squeeze, law_b.load_share = 3.0, 0.3        # set at the start: before the law's first update
    assert (law_b.squeeze, law_b.load_share) == (3.0, 0.3)
    t = a.sim.time + 0.4
    a.sim.advance(t)
    b.sim.advance(t)
    for i in (0, 1):
        np.testing.assert_array_equal(np.concatenate(a.sim.state(i)), np.concatenate(b.sim.state(i)))
    np.testing.assert_array_equal(a.sim.log.cooperation(0, 1)["squeeze"], b.sim.log.cooperation(0, 1)["squeeze"])
    c = b.sim.cooperation(0, 1)
    assert c.squeeze == pytest.approx(3.0, abs=0.3)          # the bar being lifted off the stands


def test_the_squeeze_and_load_share_follow_a_step_change_in_the_running_law():
    env = DualCarryEnv()
    env.reset(seed=3)
    law, group = env.runner.coop.law, env.runner.group
    for _ in range(15):
        obs, *_ = env.step(env.scripted_action)
    assert abs(obs["squeeze"][0]) < 0.2 and obs["load_share"][0] == pytest.approx(0.5, abs=0.03)
    share = []
    for _ in range(25):                                  # SCARA #1's share down to 0.35 for 0.5 s
        obs, r, term, trunc, info = env.step(np.array([0.0, 0.0, 0.0, 0.0, 0.35]))
        share.append(obs["load_share"][0])
        assert not term
    # under way within the first period; from 0.2 s on around the command, swinging with the lift's motion
    share = np.array(share)
    assert share[0] < 0.45 and np.mean(share[10:]) == pytest.approx(0.35, abs=0.05), share
    assert np.all(np.abs(share[10:] - 0.35) < 0.1), share
    squeeze = []
    for _ in range(25):                                  # then a step of the squeeze to 3 N for 0.5 s
        obs, r, term, trunc, info = env.step(np.array([0.0, 0.0, 0.0, 3.0, 0.35]))
        squeeze.append(obs["squeeze"][0])
        assert not term
    squeeze = np.array(squeeze)
    assert squeeze[0] > 1.0                              # within the first period (20 ms) under way
    # from 0.2 s on around the command, the welds' squeeze swinging with the carry's motion
    assert np.mean(squeeze[10:]) == pytest.approx(3.0, abs=0.3) and np.all(np.abs(squeeze[10:] - 3.0) < 1.0), squeeze
    # the same law all along, its commands changed: no law rebuilt
    assert env.runner.coop.law is law and env.runner.group == group
    assert [g["controller"] for g in env.sim.cooperatives] == [law] and (law.squeeze, law.load_share) == (3.0, 0.35)


def _offset_errors(ramp, updates=40):
    """The law's vertical object error (m) at each of `updates` updates (1 ms) after a 1 cm offset up is set
    on the running law of DualCarry's seed 1 with offset_ramp `ramp` s (None: the environment's)."""
    env = DualCarryEnv()
    env.reset(seed=1)
    law = env.runner.coop.law
    assert law.offset_ramp == pytest.approx(0.2) and np.array_equal(law.offset, np.zeros(3))
    if ramp is not None:
        law.offset_ramp = ramp
    law.offset = [0.0, 0.0, 0.01]
    sim, t0, errors = env.sim, env.sim.time, []
    for k in range(1, updates + 1):
        sim.advance(t0 + k * 1e-3)
        errors.append(law.object_error[2])
    np.testing.assert_array_equal(law.offset, [0.0, 0.0, 0.01])
    return np.array(errors)


def test_an_offset_set_on_the_law_ramps_over_its_offset_ramp():
    e = _offset_errors(0.02)
    # the reference rises 0.5 mm per update for 20 ms, the bar following behind: the error grows while the
    # ramp lasts, then the bar catches up
    assert abs(e[0]) < 2e-4 and np.all(np.diff(e[:19]) > 0) and 18 <= int(np.argmax(e)) <= 21
    assert e.max() < 5e-3 and e[30] < 0.5 * e.max()
    step = _offset_errors(0.0, updates=2)                  # no ramp: the whole centimetre at the next update
    assert step[0] == pytest.approx(0.01, abs=3e-4)


@pytest.mark.parametrize("name,value,match", [
    ("load_share", 1.5, r"^load_share must be in \[0, 1\], got 1.5$"),
    ("load_share", float("nan"), r"^load_share must be in \[0, 1\]"),
    ("squeeze", float("inf"), r"^squeeze must be finite, got inf$"),
    ("offset", [0.0, float("nan"), 0.0], r"^offset must be finite"),
    ("offset", [0.0, 0.0], r"^wrong shape for offset: expected \(3,\), got \(2,\)$"),
    ("offset_ramp", -0.1, r"^offset_ramp must be finite and >= 0, got -0.1$")])
def test_bad_commands_are_refused_by_the_law_with_the_constructors_rules(name, value, match):
    law = coopsim.ObjectControl(0.15, np.eye(3) * 1e-4)
    before = getattr(law, name)
    with pytest.raises(ValueError, match=match):
        setattr(law, name, value)
    np.testing.assert_array_equal(getattr(law, name), before)     # unchanged
    if name in ("load_share", "squeeze"):
        with pytest.raises(ValueError, match=match.split(",")[0].split(" must")[0]):
            coopsim.ObjectControl(0.15, np.eye(3) * 1e-4, **{name: value})


# ---- one agent per arm (PettingZoo) ----

def test_the_parallel_carry_passes_pettingzoo_s_api_test():
    from pettingzoo.test import parallel_api_test

    env = coopsim.envs.dual_carry_parallel()
    env.action_space("scara_1").seed(0)
    env.action_space("scara_2").seed(1)
    parallel_api_test(env, num_cycles=200)
    env.close()


def test_the_parallel_carry_with_the_scripted_actions_is_the_single_carry_and_each_arm_earns_its_term():
    par = coopsim.envs.dual_carry_parallel()
    obs, infos = par.reset(seed=3)
    single = _episode(DualCarryEnv(), 3, SCRIPTED_CARRY)
    assert set(obs) == {"scara_1", "scara_2"} and par.agents == ["scara_1", "scara_2"]
    for k in range(len(single["rewards"])):
        assert par.observation_space("scara_1").contains(obs["scara_1"])
        obs, rewards, term, trunc, infos = par.step({a: par.scripted_action for a in par.agents})
        s = single["obs"][k + 1]
        for i, a in enumerate(("scara_1", "scara_2")):
            np.testing.assert_array_equal(obs[a]["q"], s["q"][i])
            np.testing.assert_array_equal(obs[a]["wrench"], s["wrench"][i])
            np.testing.assert_array_equal(obs[a]["bar_pose"], s["bar_pose"])
            assert obs[a]["load_share"][0] == s["load_share"][i]
            terms = single["infos"][k + 1]["reward_terms"]
            assert rewards[a] == terms["arms"][i] * terms["internal_factor"]
        assert min(rewards.values()) == single["rewards"][k]
    assert all(term.values()) and par.agents == [] and infos["scara_1"]["success"]
    with pytest.raises(RuntimeError, match="reset"):
        par.step({})


def test_the_parallel_carry_merges_the_agents_commands_and_names_a_bad_one():
    par = coopsim.envs.dual_carry_parallel()
    par.reset(seed=0)
    got = par.commands({"scara_1": [0.01, 0.0, 0.002, 1.0, 0.6], "scara_2": [0.0, -0.01, 0.0, 1.5, 0.2]})
    np.testing.assert_allclose(got, [0.005, -0.005, 0.001, 2.5, 0.75])
    assert par.commands({"scara_1": np.zeros(5), "scara_2": np.zeros(5)})[4] == 0.5   # no claims: halves
    for bad, match in (({"scara_1": np.zeros(5)}, "missing 'scara_2'"),
                       ({"scara_1": np.zeros(5), "scara_2": [0, 0, 0, 0, np.nan]},
                        r"actions\['scara_2'\] must be finite"),
                       ({"scara_1": np.zeros(4), "scara_2": np.zeros(5)}, r"actions\['scara_1'\] must have shape"),
                       ({"scara_1": np.zeros(5), "scara_2": np.zeros(5), "arm_3": np.zeros(5)}, "'arm_3'")):
        with pytest.raises(ValueError, match=match) as e:
            par.step(bad)
        assert "\n" not in str(e.value)
    obs, r, term, trunc, info = par.step({a: par.scripted_action for a in par.agents})   # nothing was applied
    assert not any(term.values()) and info["scara_1"]["time"] > 0


# ---- coopsim/Handover-v0 ----

@pytest.mark.filterwarnings("ignore:.*symmetric and normalized space:UserWarning")
def test_handover_passes_check_env_and_is_registered():
    env = gym.make("coopsim/Handover-v0")
    assert isinstance(env.unwrapped, HandoverEnv)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_handover_rewards_the_task_s_outcome_of_the_handover_yaw():
    env = HandoverEnv()
    obs, info = env.reset(seed=1)
    bar = coopsim.tasks.handover.random_bar(1)
    np.testing.assert_allclose(obs, [bar[0, 3], bar[1, 3], np.arctan2(bar[1, 0], bar[0, 0])])
    assert env.observation_space.contains(obs) and info["seed"] == 1
    _, r, term, trunc, info = env.step(env.scripted_action)          # the task's 285 deg: the bar goes in
    assert (r, term, trunc) == (1.0, True, False) and info["success"] and "failure" not in info
    assert env.result.report["handover_yaw"] == pytest.approx(np.radians(285))
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.scripted_action)
    # a yaw whose grips are out of reach fails at planning. (From 310 deg on, seed 1's SCARA #2 comes to its pick
    # at 2.9 m/s and fails the grasp in the optimised build, while the sanitizers' build, rounding otherwise, has
    # one of them succeed: the plan there sits on an edge, so no such run is asserted here.)
    env.reset(seed=1)
    _, r, term, _, info = env.step([np.radians(250)])
    assert r == 0.0 and term and not info["success"] and info["failure"]["reason"]
    assert info["failure"]["step"] == "plan"
    with pytest.raises(ValueError, match=r"^action must lie in its space's bounds"):
        env.reset(seed=1)
        env.step([np.radians(340)])


def test_handover_the_same_seed_and_yaw_give_the_same_run_bit_for_bit():
    a, b = HandoverEnv(), HandoverEnv()
    runs = []
    for env in (a, b):
        obs, _ = env.reset(seed=4)
        _, r, *_ = env.step([np.radians(290)])
        runs.append((obs, r, env.result.log.to_array()))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    assert runs[0][1] == runs[1][1]
    np.testing.assert_array_equal(runs[0][2], runs[1][2])
    assert not np.array_equal(HandoverEnv().reset(seed=5)[0], runs[0][0])
