"""Collision shapes other than boxes (LinkBox.sphere, .cylinder, .hull): the world's contacts of each against
analytic cases (a hull of a cube touches and measures as the box does, spheres and cylinders on the floor at
known heights), GJK distances of hulls against hand computations, clearances against every pair, the URDF's
<collision> meshes read as convex hulls (a UR5 of example-robot-data against itself, the floor and a second
UR5: a point of one link's mesh inside another link's hull is a contact, a 5 mm gap is not), export, pickling
and bad input."""
from __future__ import annotations

import importlib.metadata
import itertools
import pickle
import warnings

import numpy as np
import pytest

import coopsim as cs

CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
H = 0.05  # the cube's half side, m


def shipped(relative: str) -> str:
    """Path of a file of the example-robot-data wheel, e.g. 'ur_description/urdf/ur5_robot.urdf'."""
    return next(str(f.locate()) for f in importlib.metadata.files("example-robot-data")
                if str(f).endswith("robots/" + relative))


UR5 = shipped("ur_description/urdf/ur5_robot.urdf")


def slider(shape):
    """A one-joint robot carrying `shape` on a prismatic joint along the world z (no gravity)."""
    return cs.Robot.from_dh([[0.0, 0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0, 0.0]], [1.0], [np.eye(3) * 0.01],
                            joint_types="P", gravity=(0, 0, 0), name="slider", boxes=[shape])


def floor_contacts(shape, z):
    """The world's contacts of `shape` (on the slider at height z) with the floor, after one step."""
    sim = cs.Simulation(dt=1e-3, world=cs.World(gravity=(0, 0, 0)), contact_forces=False)
    sim.add_robot(slider(shape), cs.PID(0.0, 0.0, 0.0, gravity_compensation=False), [z], q0=[z])
    sim.step(1)
    return [c for c in sim.contacts() if c.kind == "robot-scenery"]


def as_rows(contacts):
    """Contacts as rows (point_b, depth), sorted: for comparing two sets to round-off."""
    rows = np.array([[*c.point_b, c.depth] for c in contacts])
    return rows[np.lexsort(rows.T[::-1])] if len(rows) else rows.reshape(0, 4)


# ---- analytic cases ----

@pytest.mark.parametrize("tilt", [(0.0, 0.0), (0.3, 0.0), (0.3, 0.2), (0.0, 0.7)])
@pytest.mark.parametrize("z", [0.049, 0.04, 0.03])
def test_a_hull_of_a_cube_touches_the_floor_where_and_as_deep_as_the_box(tilt, z):
    pose = cs.dh_transform(tilt[0], 0.0, 0.0, tilt[1])
    box = floor_contacts(cs.LinkBox(1, [H, H, H], pose), z)
    hull = floor_contacts(cs.LinkBox.hull(1, H * CUBE, pose), z)
    assert box, "the box touches the floor"
    np.testing.assert_allclose(as_rows(hull), as_rows(box), rtol=0, atol=1e-12)
    # the deepest point is the cube's lowest corner
    lowest = (pose[:3, :3] @ (H * CUBE).T)[2].min() + z
    assert max(c.depth for c in hull) == pytest.approx(-lowest, abs=1e-12)


def test_a_hull_is_clear_of_the_floor_above_it():
    assert floor_contacts(cs.LinkBox.hull(1, H * CUBE), H + 0.005) == []
    assert floor_contacts(cs.LinkBox.sphere(1, H), H + 0.005) == []
    assert floor_contacts(cs.LinkBox.cylinder(1, H, 0.2), 0.1 + 0.005) == []


@pytest.mark.parametrize("depth", [1e-4, 0.003, 0.02])
def test_a_sphere_on_the_floor_at_a_known_height(depth):
    r = 0.04
    c = floor_contacts(cs.LinkBox.sphere(1, r, name="ball"), r - depth)
    assert len(c) == 1 and c[0].b == "slider/ball"
    assert c[0].depth == pytest.approx(depth, abs=1e-12)
    np.testing.assert_allclose(c[0].point_b, [0.0, 0.0, -depth], atol=1e-12)
    np.testing.assert_allclose(c[0].normal, [0.0, 0.0, -1.0], atol=1e-12)  # from the link towards the floor


@pytest.mark.parametrize("depth", [1e-4, 0.003, 0.02])
def test_a_cylinder_on_the_floor_upright_and_lying_at_known_heights(depth):
    r, length = 0.03, 0.2
    upright = floor_contacts(cs.LinkBox.cylinder(1, r, length), length / 2 - depth)
    assert upright and max(c.depth for c in upright) == pytest.approx(depth, abs=1e-9)
    for c in upright:  # on the bottom disc
        assert c.point_b[2] == pytest.approx(-depth, abs=1e-9) and np.hypot(*c.point_b[:2]) <= r + 1e-9
    lying = floor_contacts(cs.LinkBox.cylinder(1, r, length, cs.dh_transform(0, 0, 0, np.pi / 2)), r - depth)
    assert lying and max(c.depth for c in lying) == pytest.approx(depth, abs=1e-9)
    for c in lying:  # on the bottom line of the mantle
        assert c.point_b[2] == pytest.approx(-depth, abs=1e-9) and abs(c.point_b[0]) < 1e-9
        assert abs(c.point_b[1]) <= length / 2 + 1e-9


def random_pose(rng, spread):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    T = np.eye(4)
    w, x, y, z = q
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = rng.uniform(-spread, spread, 3)
    return T


def test_a_hull_of_a_cube_measures_as_the_box_separated_and_overlapping():
    rng = np.random.default_rng(7)
    half = np.array([0.05, 0.03, 0.02])
    hull = cs.LinkBox.hull(0, half * CUBE)
    box = cs.LinkBox(0, half)
    other = cs.LinkBox(0, [0.04, 0.04, 0.01])
    separated = overlapping = 0
    for _ in range(200):
        A, B = random_pose(rng, 0.08), random_pose(rng, 0.08)
        d_box = cs.box_distance(A, half, B, other.half_extents)
        assert cs.shape_distance(box, A, other, B) == d_box  # two boxes: box_distance itself
        d_hull = cs.shape_distance(hull, A, other, B)
        if d_box > 0:
            separated += 1
            assert d_hull == pytest.approx(d_box, abs=1e-12)
        else:
            overlapping += 1
            assert d_hull == pytest.approx(d_box, abs=1e-9)  # EPA against the exact separating-axis depth
    assert separated > 20 and overlapping > 20


def test_the_gjk_distance_of_two_hulls_against_a_hand_computation():
    cube = cs.LinkBox.hull(0, 0.1 * CUBE)
    octahedron = cs.LinkBox.hull(0, 0.1 * np.vstack([np.eye(3), -np.eye(3)]))
    at = np.eye(4)
    at[:3, 3] = [0.5, 0.0, 0.0]
    # a vertex of the octahedron against a face of the cube: 0.5 - 0.1 - 0.1
    assert cs.shape_distance(cube, np.eye(4), octahedron, at) == pytest.approx(0.3, abs=1e-12)
    # the cube turned 45 degrees about z: its vertical edge at 0.1 sqrt 2 faces the vertex
    turned = cs.dh_transform(np.pi / 4, 0, 0, 0)
    assert cs.shape_distance(cube, turned, octahedron, at) == pytest.approx(0.4 - 0.1 * np.sqrt(2), abs=1e-12)
    # both turned: the octahedron's vertex (0, 0.1, 0) rotated to (-0.1/sqrt2, 0.1/sqrt2) faces nothing nearer
    # than its vertex (-0.1, 0, 0) at x = 0.5 - 0.1 / sqrt2 ... measured along x: edge of the cube at
    # 0.1 sqrt 2, the octahedron's nearest points the edge between two vertices at x = 0.5 - 0.1 cos 45
    both = at @ turned
    d = cs.shape_distance(cube, turned, octahedron, both)
    assert d == pytest.approx(0.5 - 0.1 / np.sqrt(2) - 0.1 * np.sqrt(2), abs=1e-12)
    # a sphere and a cylinder: centre distances less radii
    ball = cs.LinkBox.sphere(0, 0.05)
    rod = cs.LinkBox.cylinder(0, 0.02, 0.3)
    # (GJK on a sphere and a cylinder, implicit shapes, stops within its tolerance: 1e-11 m here)
    assert cs.shape_distance(ball, at, rod, np.eye(4)) == pytest.approx(0.5 - 0.05 - 0.02, abs=1e-10)
    assert cs.shape_distance(ball, at, cube, np.eye(4)) == pytest.approx(0.5 - 0.05 - 0.1, abs=1e-10)
    # overlapping: a sphere sunk 1 cm into the cube's face
    at[:3, 3] = [0.14, 0.0, 0.0]
    assert cs.shape_distance(ball, at, cube, np.eye(4)) == pytest.approx(-0.01, abs=1e-9)


def test_shape_clearances_are_the_smallest_shape_distance_of_every_pair():
    rng = np.random.default_rng(3)
    shapes_a = [cs.LinkBox.hull(0, rng.normal(size=(12, 3)) * 0.05), cs.LinkBox.sphere(0, 0.03),
                cs.LinkBox(0, [0.02, 0.05, 0.01])]
    shapes_b = [cs.LinkBox.cylinder(0, 0.02, 0.1), cs.LinkBox.hull(0, rng.normal(size=(30, 3)) * 0.04)]
    rows = 40
    PA = np.array([[random_pose(rng, 0.15) for _ in shapes_a] for _ in range(rows)])
    PB = np.array([[random_pose(rng, 0.15) for _ in shapes_b] for _ in range(rows)])
    d, ia, ib = cs.shape_clearances(PA, shapes_a, PB, shapes_b)
    for r in range(rows):
        all_pairs = np.array([[cs.shape_distance(a, PA[r, i], b, PB[r, j]) for j, b in enumerate(shapes_b)]
                              for i, a in enumerate(shapes_a)])
        assert d[r] == pytest.approx(all_pairs.min(), abs=1e-12)
        assert all_pairs[ia[r], ib[r]] == d[r]
    # boxes alone: box_clearances' values
    boxes = [cs.LinkBox(0, [0.02, 0.05, 0.01]), cs.LinkBox(0, [0.03, 0.01, 0.04])]
    np.testing.assert_array_equal(cs.shape_clearances(PA[:, :2], boxes, PB, boxes)[0],
                                  cs.box_clearances(PA[:, :2], [b.half_extents for b in boxes], PB,
                                                    [b.half_extents for b in boxes])[0])


# ---- the UR5 with its collision meshes ----

@pytest.fixture(scope="module")
def ur5():
    return cs.Robot.from_urdf(UR5)


def test_the_ur5_collides_as_the_convex_hulls_of_its_collision_meshes(ur5):
    import trimesh

    hulls = [b for b in ur5.boxes if b.kind == "hull"]
    assert [b.link for b in hulls] == list(range(7))  # the base and each of the six links
    assert all(len(b.points) == 64 for b in hulls)
    # the points kept are vertices of the mesh's hull, in the link's frame (the wrist 3 link: its mesh
    # lies in the URDF link's frame, here moved to DH frame 6)
    mesh = trimesh.load(shipped("ur_description/meshes/ur5/collision/forearm.stl"), force="mesh")
    fore = next(b for b in hulls if b.link == 3)
    assert len(mesh.convex_hull.vertices) > 64
    # the hull's own dimensions: its extent along each of its axes matches the mesh's (the extremes kept)
    ext = np.ptp(fore.points, axis=0)
    assert sorted(ext) == pytest.approx(sorted(np.ptp(mesh.vertices, axis=0)), rel=0.02)
    small = cs.Robot.from_urdf(UR5, hull_points=8)
    assert all(len(b.points) == 8 for b in small.boxes if b.kind == "hull")


def world_contacts(robots, qs, kinds):
    """The world's contacts of `kinds` with the robots at rest at qs (no gravity: they stay there)."""
    sim = cs.Simulation(dt=1e-3, world=cs.World(gravity=(0, 0, 0)), contact_forces=False)
    for r, q in zip(robots, qs):
        sim.add_robot(r.with_gravity([0, 0, 0]), cs.PID(0.0, 0.0, 0.0, gravity_compensation=False), q, q0=q)
    sim.step(1)
    return [c for c in sim.contacts() if c.kind in kinds and c.depth >= 0]


def bisect(f, lo, hi, target, steps=60):
    """s in [lo, hi] where f(s) = target (f(lo) - target and f(hi) - target of opposite signs)."""
    flo = f(lo) - target
    assert flo * (f(hi) - target) < 0
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        fm = f(mid) - target
        if (fm < 0) == (flo < 0):
            lo, flo = mid, fm
        else:
            hi = mid
    return 0.5 * (lo + hi)


def lowest_point(robot, q):
    """The lowest hull vertex (z, m) of the robot's moving links at q: their distance to the floor."""
    P, _ = robot.shapes(q)
    return min((P[k][:3, :3] @ b.points.T + P[k][:3, 3:])[2].min()
               for k, b in enumerate(robot.boxes) if b.kind == "hull" and b.link > 0)


@pytest.mark.parametrize("gap", [0.005, -0.005])
def test_a_ur5_against_the_floor_touches_it_by_its_meshes(ur5, gap):
    # the shoulder lifted (s < 0) from the arm level with it (s = 0: the wrist below the floor)
    s = bisect(lambda s: lowest_point(ur5, [0, s, 0, 0, 0, 0]), -0.5, 0.0, gap)
    q = [0, s, 0, 0, 0, 0]
    found = world_contacts([ur5], [q], {"robot-scenery"})
    if gap > 0:
        assert found == []
    else:
        assert found and max(c.depth for c in found) == pytest.approx(-gap, abs=1e-9)


def self_clearance(robot, q, pairs):
    P, _ = robot.shapes(q)
    S = robot.boxes
    return min(cs.shape_distance(S[i], P[i], S[j], P[j]) for i, j in pairs)


@pytest.mark.parametrize("gap", [0.005, -0.005])
def test_a_ur5_folded_onto_itself_touches_itself_by_its_meshes(ur5, gap):
    sim = cs.Simulation(dt=1e-3)
    sim.add_robot(ur5, cs.PID(0.0, 0.0, 0.0), np.zeros(6))
    excluded = {frozenset(p) for p in sim.excluded_pairs(0)}
    names = [b.name for b in ur5.boxes]
    pairs = [(i, j) for i, j in itertools.combinations(range(len(names)), 2)
             if frozenset((names[i], names[j])) not in excluded]
    assert (2, 4) in pairs  # the upper arm and the first wrist link are tested
    e = bisect(lambda e: self_clearance(ur5, [0, 0, -e, 0, 0, 0], pairs), 2.7, 2.9, gap)
    found = world_contacts([ur5], [[0, 0, -e, 0, 0, 0]], {"self"})
    if gap > 0:
        assert found == []
    else:
        # Bullet's separating axes and face clipping in the world, coopsim's separating axes in shape_distance:
        # where two hulls meet edge on edge the clipped face reports a point up to a micrometre deeper
        assert found and max(c.depth for c in found) == pytest.approx(-gap, abs=1e-6)


def arm_clearance(a, b, q):
    (PA, _), (PB, _) = a.shapes(q), b.shapes(q)
    return cs.shape_clearances(PA[None], a.boxes, PB[None], b.boxes)[0][0]


@pytest.mark.parametrize("gap", [0.005, -0.005])
def test_two_ur5s_touch_each_other_by_their_meshes(ur5, gap):
    q = [0.0, -0.3, 0.5, 0.0, 0.0, 0.0]
    other = lambda x: ur5.with_base([x, 0.02, 0.0], np.pi)  # facing the first, arms reaching towards it
    x = bisect(lambda x: arm_clearance(ur5, other(x), q), 1.45, 1.9, gap)
    found = world_contacts([ur5, other(x)], [q, q], {"robot-robot"})
    if gap > 0:
        assert found == []
    else:
        # Bullet's separating axes and face clipping in the world, coopsim's separating axes in shape_distance:
        # where two hulls meet edge on edge the clipped face reports a point up to a micrometre deeper
        assert found and max(c.depth for c in found) == pytest.approx(-gap, abs=1e-6)


# ---- URDF in and out ----

def urdf_of(geometry, extra=""):
    return f"""<robot name="r">
  <link name="base"/>
  <link name="arm">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.1 0 0" rpy="0 0.3 0"/><geometry>{geometry}</geometry></collision>{extra}
  </link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
</robot>"""


def test_urdf_spheres_and_cylinders_are_bullets_own_and_come_back_from_the_export():
    ball = cs.Robot.from_urdf(urdf_of('<sphere radius="0.04"/>'))
    rod = cs.Robot.from_urdf(urdf_of('<cylinder radius="0.02" length="0.3"/>'))
    assert [(b.kind, b.radius) for b in ball.boxes] == [("sphere", 0.04)]
    assert [(b.kind, b.radius, b.length) for b in rod.boxes] == [("cylinder", 0.02, 0.3)]
    for r in (ball, rod):
        back = cs.Robot.from_urdf(r.to_urdf())
        (a,), (b,) = r.boxes, back.boxes
        assert (a.kind, a.radius, a.length) == (b.kind, b.radius, b.length)
        np.testing.assert_allclose(b.pose, a.pose, atol=1e-12)


def test_a_hull_is_exported_as_its_bounding_box(ur5):
    text = ur5.to_urdf()
    assert "<mesh" not in text
    back = cs.Robot.from_urdf(text)
    assert [b.kind for b in back.boxes] == ["box"] * len(ur5.boxes)
    for a, b in zip(ur5.boxes, back.boxes):
        np.testing.assert_allclose(b.half_extents, a.half_extents, rtol=1e-12)
        np.testing.assert_allclose(b.pose, a.pose, atol=1e-12)


def test_a_mesh_that_cannot_be_read_is_left_out_with_a_warning_naming_it(tmp_path):
    bad = tmp_path / "broken.stl"
    bad.write_bytes(b"not a mesh at all")
    for fn in (str(bad), "package://nowhere/missing.stl"):
        with pytest.warns(RuntimeWarning, match=r"collision mesh '.*(broken|missing)\.stl' could not be read.*"
                                                r"default boxes"):
            r = cs.Robot.from_urdf(urdf_of(f'<mesh filename="{fn}"/>'))
        assert r.has_default_boxes if hasattr(r, "has_default_boxes") else True
        assert [b.kind for b in r.boxes] == ["box"]  # the default box along the link


def test_a_readable_mesh_becomes_a_hull_scaled(tmp_path):
    import trimesh

    path = tmp_path / "block.stl"
    trimesh.creation.box(extents=[0.2, 0.1, 0.05]).export(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = cs.Robot.from_urdf(urdf_of(f'<mesh filename="{path}" scale="0.5 1 2"/>'))
    (b,) = r.boxes
    assert b.kind == "hull" and len(b.points) == 8
    np.testing.assert_allclose(b.half_extents, [0.05, 0.05, 0.05], atol=1e-12)


# ---- pickling and bad input ----

def test_shapes_pickle_as_they_were_made():
    rng = np.random.default_rng(1)
    for s in (cs.LinkBox.sphere(2, 0.1, name="s"), cs.LinkBox.cylinder(1, 0.02, 0.3, cs.dh_transform(0.1, 0.2, 0.3, 0.4)),
              cs.LinkBox.hull(3, rng.normal(size=(20, 3)), cs.dh_transform(0.4, 0.1, 0.0, 0.2), "h"),
              cs.LinkBox(0, [0.1, 0.2, 0.3])):
        t = pickle.loads(pickle.dumps(s))
        assert (t.kind, t.link, t.name, t.radius, t.length) == (s.kind, s.link, s.name, s.radius, s.length)
        np.testing.assert_array_equal(t.points, s.points)
        np.testing.assert_array_equal(t.pose, s.pose)
        np.testing.assert_array_equal(t.half_extents, s.half_extents)


def test_a_hull_is_kept_about_the_centre_of_its_bounding_box():
    pts = CUBE * [0.1, 0.2, 0.3] + [1.0, 2.0, 3.0]
    h = cs.LinkBox.hull(1, pts, cs.dh_transform(0.5, 0, 0, 0))
    np.testing.assert_allclose(h.half_extents, [0.1, 0.2, 0.3], atol=1e-12)
    world = h.pose[:3, :3] @ h.points.T + h.pose[:3, 3:]
    np.testing.assert_allclose(world.T, (cs.dh_transform(0.5, 0, 0, 0) @ np.c_[pts, np.ones(8)].T)[:3].T, atol=1e-12)


@pytest.mark.parametrize("make, message", [
    (lambda: cs.LinkBox.sphere(1, 0.0), r"^sphere: radius must be finite and > 0 m, got 0"),
    (lambda: cs.LinkBox.cylinder(1, 0.1, -1.0), r"^cylinder: length must be finite and > 0 m, got -1"),
    (lambda: cs.LinkBox.cylinder(1, np.nan, 1.0), r"^cylinder: radius must be finite and > 0 m, got nan"),
    (lambda: cs.LinkBox.hull(1, CUBE[:3]), r"^hull: a hull needs 4 \.\. 4096 points, got 3$"),
    (lambda: cs.LinkBox.hull(1, CUBE[:4]), r"^hull: hull points must span a volume"),
    (lambda: cs.LinkBox.hull(1, np.r_[CUBE, [[np.inf, 0, 0]]]), r"^hull: hull points must be finite$"),
    (lambda: cs.LinkBox.hull(1, CUBE[:, :2]), r"points"),
    (lambda: cs.Robot.from_urdf(UR5, hull_points=3), r"^hull_points must be an integer in 4 \.\. 4096, got 3$"),
    (lambda: cs.shape_clearances(np.zeros((2, 1, 4, 4)), [cs.LinkBox.sphere(0, 1.0)] * 2, np.eye(4)[None],
                                 [cs.LinkBox.sphere(0, 1.0)]), r"poses_a"),
])
def test_bad_shapes_are_one_line_errors(make, message):
    with pytest.raises(ValueError, match=message) as e:
        make()
    assert "\n" not in str(e.value)


def test_a_clamp_keeps_the_last_links_hull_and_meshes_can_be_left_out(ur5):
    clamped = cs.robots.add_clamp(ur5)
    assert [b.kind for b in clamped.boxes if b.link == 6 and b.name == "wrist_3_link_0"] == ["hull"]
    plain = cs.Robot.from_urdf(UR5, collision_meshes=False)
    assert [b.kind for b in plain.boxes] == ["box"] and plain.boxes[0].name == "ee_link_0"
