// Distances between convex shapes, free of any world: Bullet's GJK (margins zero, double precision) for
// separated shapes; for overlapping boxes the separating-axis overlap of geometry.cpp (box_gap), for
// any other overlapping pair (spheres, cylinders, convex hulls) Bullet's EPA; and the clearance of two
// moving sets of shapes over many configurations with few GJK calls.
#include "coopsim/box_distance.hpp"
#include "coopsim/robot.hpp"
#include "bullet_hull.hpp"

#include <BulletCollision/CollisionShapes/btBoxShape.h>
#include <BulletCollision/CollisionShapes/btConvexHullShape.h>
#include <BulletCollision/CollisionShapes/btConvexPolyhedron.h>
#include <BulletCollision/CollisionShapes/btCylinderShape.h>
#include <BulletCollision/CollisionShapes/btSphereShape.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkEpaPenetrationDepthSolver.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkPairDetector.h>
#include <BulletCollision/NarrowPhaseCollision/btPointCollector.h>
#include <BulletCollision/NarrowPhaseCollision/btVoronoiSimplexSolver.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

namespace coopsim {

namespace {

btTransform bt_pose(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.rotation();
  btTransform t;
  t.setBasis(btMatrix3x3(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)));
  t.setOrigin(btVector3(T.translation().x(), T.translation().y(), T.translation().z()));
  return t;
}

void check_half(const Eigen::Vector3d& h, const char* what) {
  if (!h.allFinite() || (h.array() <= 0.0).any())
    throw std::invalid_argument(std::string(what) + ": half extents must be finite and > 0 m");
}

// Bullet's GJK (EPA where they overlap) on two convex shapes at their transforms: the closest points found.
btPointCollector closest_points(const btConvexShape& a, const btTransform& ta, const btConvexShape& b,
                                const btTransform& tb) {
  btVoronoiSimplexSolver simplex;
  btGjkEpaPenetrationDepthSolver epa;
  btGjkPairDetector gjk(&a, &b, &simplex, &epa);
  btDiscreteCollisionDetectorInterface::ClosestPointInput in;
  in.m_transformA = ta;
  in.m_transformB = tb;
  btPointCollector out;
  gjk.getClosestPoints(in, out, nullptr);
  return out;
}

// The gap by GJK; overlapping boxes get minus the separating-axis overlap,
// which for boxes is the exact penetration depth (the 15 axes hold every
// candidate direction of the minimum translation), where EPA is not exact.
// `gap`, `exact`: box_gap of the pair; when it is the distance, no GJK.
double gjk_distance(const btBoxShape& a, const btTransform& ta, const btBoxShape& b, const btTransform& tb,
                    const Eigen::Isometry3d& ea, const Eigen::Vector3d& ha, const Eigen::Isometry3d& eb,
                    const Eigen::Vector3d& hb, double gap, bool exact) {
  if (exact) return gap;
  if (gap <= 0) return gap;  // they overlap (the separating-axis depth), or touch
  const btPointCollector out = closest_points(a, ta, b, tb);
  // GJK's distance is at least the separating-axis bound, up to its own round-off
  if (out.m_hasResult && out.m_distance > 0.0) return std::max(out.m_distance, gap);
  return gap;  // no result: the separating-axis bound is the best known
}

double exact_distance(const btBoxShape& a, const btTransform& ta, const btBoxShape& b, const btTransform& tb,
                      const Eigen::Isometry3d& ea, const Eigen::Vector3d& ha, const Eigen::Isometry3d& eb,
                      const Eigen::Vector3d& hb) {
  bool exact = false;
  const double gap = box_gap(ea, ha, eb, hb, &exact);
  return gjk_distance(a, ta, b, tb, ea, ha, eb, hb, gap, exact);
}

btBoxShape zero_margin_box(const Eigen::Vector3d& h) {
  btBoxShape box(btVector3(h.x(), h.y(), h.z()));
  box.setMargin(0.0);  // keeps the half extents: the box is exact, not rounded
  return box;
}

// Bullet's shape of a Shape for GJK, margins zero as the world's (a sphere's margin is its radius).
std::unique_ptr<btConvexShape> gjk_shape(const Shape& s) {
  switch (s.type) {
    case ShapeKind::Sphere:
      return std::make_unique<btSphereShape>(s.radius);
    case ShapeKind::Cylinder: {
      auto c = std::make_unique<btCylinderShapeZ>(btVector3(s.radius, s.radius, s.half_length));
      c->setMargin(0.0);
      return c;
    }
    case ShapeKind::Hull: {
      auto h = std::make_unique<btConvexHullShape>();
      for (const Eigen::Vector3d& p : s.points) h->addPoint(btVector3(p.x(), p.y(), p.z()), false);
      h->setMargin(0.0);
      h->recalcLocalAabb();
      return h;
    }
    default: {
      auto b = std::make_unique<btBoxShape>(btVector3(s.half_extents.x(), s.half_extents.y(), s.half_extents.z()));
      b->setMargin(0.0);
      return b;
    }
  }
}

// The distance of two shapes of which one at least is not a box: GJK (separated), EPA (overlapping);
// `lower`, a lower bound of it (the gap of their bounds), where GJK finds no result.
double convex_distance(const btConvexShape& a, const btTransform& ta, const btConvexShape& b, const btTransform& tb,
                       double lower) {
  const btPointCollector out = closest_points(a, ta, b, tb);
  if (!out.m_hasResult) return lower;
  return std::max<double>(out.m_distance, lower);
}

bool polyhedral(const Shape& s) { return s.type == ShapeKind::Box || s.type == ShapeKind::Hull; }

// The depth of the overlap of two convex polyhedra (a box's or a hull's faces and edges, Bullet's
// initializePolyhedralFeatures) at their poses, m (> 0), by their separating axes: the smallest overlap
// of their projections over each face normal of either and each cross product of an edge direction of
// one with one of the other, which holds the direction of the smallest translation that parts them
// (exact, where EPA converges to a tolerance). < 0 when some axis separates them.
double polyhedra_depth(const btConvexPolyhedron& a, const btTransform& ta, const btConvexPolyhedron& b,
                       const btTransform& tb) {
  thread_local std::vector<btVector3> va, vb;
  va.resize(a.m_vertices.size());
  vb.resize(b.m_vertices.size());
  for (int i = 0; i < a.m_vertices.size(); ++i) va[i] = ta(a.m_vertices[i]);
  for (int i = 0; i < b.m_vertices.size(); ++i) vb[i] = tb(b.m_vertices[i]);
  double depth = std::numeric_limits<double>::infinity();
  auto along = [&](const btVector3& n) {
    double lo_a = kInf, hi_a = -kInf, lo_b = kInf, hi_b = -kInf;
    for (const btVector3& v : va) {
      const double x = v.dot(n);
      lo_a = std::min(lo_a, x);
      hi_a = std::max(hi_a, x);
    }
    for (const btVector3& v : vb) {
      const double x = v.dot(n);
      lo_b = std::min(lo_b, x);
      hi_b = std::max(hi_b, x);
    }
    depth = std::min(depth, std::min(hi_a - lo_b, hi_b - lo_a));
  };
  for (int f = 0; f < a.m_faces.size(); ++f) {
    const auto& pl = a.m_faces[f].m_plane;
    along(ta.getBasis() * btVector3(pl[0], pl[1], pl[2]));
  }
  for (int f = 0; f < b.m_faces.size(); ++f) {
    const auto& pl = b.m_faces[f].m_plane;
    along(tb.getBasis() * btVector3(pl[0], pl[1], pl[2]));
  }
  for (int i = 0; i < a.m_uniqueEdges.size(); ++i) {
    const btVector3 ea = ta.getBasis() * a.m_uniqueEdges[i];
    for (int j = 0; j < b.m_uniqueEdges.size(); ++j) {
      const btVector3 n = ea.cross(tb.getBasis() * b.m_uniqueEdges[j]);
      const double len = n.length();
      if (len > 1e-9 * ea.length() * b.m_uniqueEdges[j].length()) along(n / len);
    }
  }
  return depth;
}

// A set of shapes ready for the distance of any pair: the shapes checked (their bounds set), Bullet's
// shapes, bounding radii; a hull's faces and edges made when first needed (polyhedra_depth).
struct ShapeSet {
  std::vector<Shape> shape;
  std::vector<std::unique_ptr<btConvexShape>> bt;
  mutable std::vector<char> features;  // initializePolyhedralFeatures done
  const btConvexPolyhedron& polyhedron(size_t i) const {
    auto& p = static_cast<btPolyhedralConvexShape&>(*bt[i]);
    if (!features[i]) {
      if (shape[i].type == ShapeKind::Hull) {  // the exact vertices (bullet_hull.hpp)
        const auto h = detail::exact_hull(shape[i].points, true);
        btConvexPolyhedron copy = *h->getConvexPolyhedron();
        p.setPolyhedralFeatures(copy);
      } else {
        p.initializePolyhedralFeatures();
      }
      features[i] = 1;
    }
    return *p.getConvexPolyhedron();
  }
  std::vector<double> radius;  // of the sphere about the frame's origin that holds the shape
  explicit ShapeSet(const std::vector<Shape>& shapes, const char* what) {
    shape = shapes;
    for (Shape& s : shape) {
      if (s.is_box()) check_half(s.half_extents, what);
      else finish_shape(s, what);
      bt.push_back(gjk_shape(s));
      features.push_back(0);
      double r = s.half_extents.norm();
      if (s.type == ShapeKind::Sphere) r = s.radius;
      if (s.type == ShapeKind::Hull) {
        r = 0.0;
        for (const Eigen::Vector3d& p : s.points) r = std::max(r, p.norm());
      }
      radius.push_back(r);
    }
  }
};

// The distance of shapes i of A and j of B at their poses; `gap`, `certain`: box_gap of their bounds.
double pair_distance(const ShapeSet& A, size_t i, const Eigen::Isometry3d& ea, const ShapeSet& B, size_t j,
                     const Eigen::Isometry3d& eb, double gap, bool certain) {
  const Shape &a = A.shape[i], &b = B.shape[j];
  if (a.is_box() && b.is_box())
    return gjk_distance(static_cast<const btBoxShape&>(*A.bt[i]), bt_pose(ea), static_cast<const btBoxShape&>(*B.bt[j]),
                        bt_pose(eb), ea, a.half_extents, eb, b.half_extents, gap, certain);
  const btTransform ta = bt_pose(ea), tb = bt_pose(eb);
  const double d = convex_distance(*A.bt[i], ta, *B.bt[j], tb, gap);
  if (d > 0 || !polyhedral(a) || !polyhedral(b)) return d;
  // two polyhedra overlapping: the exact depth by their separating axes rather than EPA's
  const double depth = polyhedra_depth(A.polyhedron(i), ta, B.polyhedron(j), tb);
  return depth >= 0 ? -depth : d;
}

}  // namespace

double shape_distance(const Shape& a, const Eigen::Isometry3d& pose_a, const Shape& b, const Eigen::Isometry3d& pose_b) {
  const std::vector<Shape> va{a}, vb{b};
  const ShapeSet A(va, "shape_a"), B(vb, "shape_b");
  bool certain = false;
  const double gap = box_gap(pose_a, A.shape[0].half_extents, pose_b, B.shape[0].half_extents, &certain);
  return pair_distance(A, 0, pose_a, B, 0, pose_b, gap, certain);
}

double box_distance(const Eigen::Isometry3d& a, const Eigen::Vector3d& half_a, const Eigen::Isometry3d& b,
                    const Eigen::Vector3d& half_b) {
  check_half(half_a, "half_a");
  check_half(half_b, "half_b");
  const btBoxShape ba = zero_margin_box(half_a), bb = zero_margin_box(half_b);
  return exact_distance(ba, bt_pose(a), bb, bt_pose(b), a, half_a, b, half_b);
}

void box_distances(const std::vector<Eigen::Isometry3d>& a, const std::vector<Eigen::Vector3d>& half_a,
                   const std::vector<Eigen::Isometry3d>& b, const std::vector<Eigen::Vector3d>& half_b,
                   double* out) {
  if (a.size() != half_a.size() || b.size() != half_b.size())
    throw std::invalid_argument("box_distances: as many half extents as poses are needed");
  std::vector<btBoxShape> sa, sb;
  std::vector<btTransform> ta, tb;
  sa.reserve(a.size());
  sb.reserve(b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    check_half(half_a[i], "half_a");
    sa.push_back(zero_margin_box(half_a[i]));
    ta.push_back(bt_pose(a[i]));
  }
  for (size_t j = 0; j < b.size(); ++j) {
    check_half(half_b[j], "half_b");
    sb.push_back(zero_margin_box(half_b[j]));
    tb.push_back(bt_pose(b[j]));
  }
  for (size_t i = 0; i < a.size(); ++i)
    for (size_t j = 0; j < b.size(); ++j) out[i * b.size() + j] = exact_distance(sa[i], ta[i], sb[j], tb[j], a[i], half_a[i], b[j], half_b[j]);
}

void shape_clearances(int rows, const std::vector<Eigen::Isometry3d>& a, const std::vector<Shape>& shapes_a,
                      const std::vector<Eigen::Isometry3d>& b, const std::vector<Shape>& shapes_b, bool b_static,
                      double* d, long* ia, long* ib) {
  const size_t na = shapes_a.size(), nb = shapes_b.size(), n = static_cast<size_t>(std::max(rows, 0));
  if (rows < 0) throw std::invalid_argument("box_clearances: rows must be >= 0");
  if (na == 0 || nb == 0) throw std::invalid_argument("box_clearances: both sets need at least one box");
  if (a.size() != n * na || b.size() != (b_static ? nb : n * nb))
    throw std::invalid_argument("box_clearances: as many poses as rows times boxes are needed");
  const ShapeSet SA(shapes_a, "half_a"), SB(shapes_b, "half_b");
  const std::vector<double>&ra = SA.radius, &rb = SB.radius;
  std::vector<Eigen::Vector3d> half_a, half_b;  // the bounds
  for (const Shape& s : SA.shape) half_a.push_back(s.half_extents);
  for (const Shape& s : SB.shape) half_b.push_back(s.half_extents);
  // Lower bounds of each pair's distance carried from row to row: a bound at one row, less how far
  // any point of either box can have moved since (its centre's displacement plus its radius times
  // the change of its rotation matrix, Frobenius norm), still bounds the distance. Most pairs are
  // ruled out by it for many rows after one look.
  const double slack = 1e-12;  // round-off of the bounds, m
  std::vector<double> moved_a(na, 0.0), moved_b(nb, 0.0);             // cumulative motion bound per box
  std::vector<double> bound(na * nb, -std::numeric_limits<double>::infinity()), at(na * nb, 0.0);
  auto motion = [](const Eigen::Isometry3d& now, const Eigen::Isometry3d& before, double radius) {
    return (now.translation() - before.translation()).norm() + radius * (now.linear() - before.linear()).norm();
  };
  long pi = -1, pj = -1;
  for (size_t r = 0; r < n; ++r) {
    const Eigen::Isometry3d* A = &a[r * na];
    const Eigen::Isometry3d* B = b_static ? b.data() : &b[r * nb];
    if (r > 0) {
      for (size_t i = 0; i < na; ++i) moved_a[i] += motion(A[i], a[(r - 1) * na + i], ra[i]);
      if (!b_static)
        for (size_t j = 0; j < nb; ++j) moved_b[j] += motion(B[j], b[(r - 1) * nb + j], rb[j]);
    }
    double best = std::numeric_limits<double>::infinity();
    long bi = -1, bj = -1;
    // a pair's distance, exact; remembered as its bound
    auto exact = [&](size_t i, size_t j, double gap, bool certain) {
      const double e = pair_distance(SA, i, A[i], SB, j, B[j], gap, certain);
      bound[i * nb + j] = e;
      at[i * nb + j] = moved_a[i] + moved_b[j];
      if (e < best) {
        best = e;
        bi = static_cast<long>(i);
        bj = static_cast<long>(j);
      }
    };
    if (pi >= 0) {  // the previous row's nearest pair first: a tight bound for the others
      bool certain = false;
      const double gap = box_gap(A[pi], half_a[pi], B[pj], half_b[pj], &certain);
      exact(static_cast<size_t>(pi), static_cast<size_t>(pj), gap, certain);
    }
    for (size_t i = 0; i < na; ++i)
      for (size_t j = 0; j < nb; ++j) {
        if (static_cast<long>(i) == pi && static_cast<long>(j) == pj) continue;
        const size_t k = i * nb + j;
        // three lower bounds of the distance, the cheapest first
        double lb = bound[k] - (moved_a[i] + moved_b[j] - at[k]);
        if (lb - slack >= best) continue;
        const double sphere = (A[i].translation() - B[j].translation()).norm() - ra[i] - rb[j];  // (a lower bound)
        if (sphere > lb) {
          lb = bound[k] = sphere;
          at[k] = moved_a[i] + moved_b[j];
          if (lb - slack >= best) continue;
        }
        bool certain = false;
        const double gap = box_gap(A[i], half_a[i], B[j], half_b[j], &certain);
        if (gap > lb) {
          bound[k] = gap;
          at[k] = moved_a[i] + moved_b[j];
          if (gap - slack >= best) continue;
        }
        exact(i, j, gap, certain);
      }
    d[r] = best;
    ia[r] = pi = bi;
    ib[r] = pj = bj;
  }
}

void box_clearances(int rows, const std::vector<Eigen::Isometry3d>& a, const std::vector<Eigen::Vector3d>& half_a,
                    const std::vector<Eigen::Isometry3d>& b, const std::vector<Eigen::Vector3d>& half_b,
                    bool b_static, double* d, long* ia, long* ib) {
  std::vector<Shape> sa(half_a.size()), sb(half_b.size());
  for (size_t i = 0; i < sa.size(); ++i) sa[i].half_extents = half_a[i];
  for (size_t j = 0; j < sb.size(); ++j) sb[j].half_extents = half_b[j];
  shape_clearances(rows, a, sa, b, sb, b_static, d, ia, ib);
}

namespace {

// n half extents from a (n, 3) table.
std::vector<Eigen::Vector3d> halves(const Array& h, std::ptrdiff_t n, const char* name) {
  check_shape(h, {n, 3}, name);
  check_finite(h, name);
  std::vector<Eigen::Vector3d> out;
  for (std::ptrdiff_t i = 0; i < n; ++i) out.emplace_back(h.values[3 * i], h.values[3 * i + 1], h.values[3 * i + 2]);
  return out;
}

// The k-th pose of a table of poses (its rows of `per_row` poses when per_row > 0), named "NAME[r][i]".
Eigen::Isometry3d pose_at(const ArrayView& a, std::ptrdiff_t k, std::ptrdiff_t per_row, const char* name) {
  return rigid_pose(a.values + 16 * k, [&] {
    std::string who = name;
    if (per_row > 0) who += "[" + std::to_string(k / per_row) + "]";
    return who + "[" + std::to_string(per_row > 0 ? k % per_row : k) + "]";
  });
}

// The poses of a table of `count` poses (rows of `per_row` when per_row > 0), each checked.
std::vector<Eigen::Isometry3d> poses_of(const ArrayView& a, std::ptrdiff_t count, std::ptrdiff_t per_row, const char* name) {
  std::vector<Eigen::Isometry3d> out;
  out.reserve(static_cast<size_t>(count));
  for (std::ptrdiff_t k = 0; k < count; ++k) out.push_back(pose_at(a, k, per_row, name));
  return out;
}

}  // namespace

double box_distance(const Array& pose_a, const Array& half_a, const Array& pose_b, const Array& half_b) {
  const Eigen::Isometry3d a = rigid_pose(pose_a, "pose_a"), b = rigid_pose(pose_b, "pose_b");
  return box_distance(a, vector_of(half_a, 3, "half_a"), b, vector_of(half_b, 3, "half_b"));
}

Array box_distances(const Array& poses_a, const Array& half_a, const Array& poses_b, const Array& half_b,
                    bool pairwise) {
  const auto a = rigid_poses(poses_a, "poses_a"), b = rigid_poses(poses_b, "poses_b");
  const std::ptrdiff_t na = static_cast<std::ptrdiff_t>(a.size()), nb = static_cast<std::ptrdiff_t>(b.size());
  const auto x = halves(half_a, na, "half_a"), y = halves(half_b, nb, "half_b");
  if (pairwise && na != nb)
    throw std::invalid_argument("pairwise: poses_a and poses_b must have the same length, got " + std::to_string(na) +
                                " and " + std::to_string(nb));
  Array out{std::vector<double>(pairwise ? na : na * nb), {na}};
  if (!pairwise) out.shape.push_back(nb);
  if (!pairwise) box_distances(a, x, b, y, out.values.data());
  for (std::ptrdiff_t i = 0; pairwise && i < na; ++i) out.values[i] = box_distance(a[i], x[i], b[i], y[i]);
  return out;
}

BoxClearances box_clearances(const ArrayView& poses_a, const Array& half_a, const ArrayView& poses_b, const Array& half_b) {
  check_shape(poses_a, {-1, -1, 4, 4}, "poses_a");
  check_finite(poses_a, "poses_a");
  const std::ptrdiff_t rows = poses_a.shape[0], na = poses_a.shape[1];
  const auto x = halves(half_a, na, "half_a");
  const bool fixed = poses_b.ndim() == 3;  // boxes that do not move
  if (fixed) check_shape(poses_b, {-1, 4, 4}, "poses_b");
  else check_shape(poses_b, {rows, -1, 4, 4}, "poses_b");
  check_finite(poses_b, "poses_b");
  const std::ptrdiff_t nb = fixed ? poses_b.shape[0] : poses_b.shape[1];
  const auto y = halves(half_b, nb, "half_b");
  if (na == 0 || nb == 0) throw std::invalid_argument("poses_a and poses_b need at least one box each");
  const auto a = poses_of(poses_a, rows * na, na, "poses_a"), b = poses_of(poses_b, fixed ? nb : rows * nb, fixed ? 0 : nb, "poses_b");
  BoxClearances out{std::vector<double>(rows), std::vector<long>(rows), std::vector<long>(rows)};
  box_clearances(static_cast<int>(rows), a, x, b, y, fixed, out.d.data(), out.ia.data(), out.ib.data());
  return out;
}

BoxClearances shape_clearances(const ArrayView& poses_a, const std::vector<Shape>& shapes_a, const ArrayView& poses_b,
                               const std::vector<Shape>& shapes_b) {
  const std::ptrdiff_t na = static_cast<std::ptrdiff_t>(shapes_a.size()), nb = static_cast<std::ptrdiff_t>(shapes_b.size());
  if (na == 0 || nb == 0) throw std::invalid_argument("shapes_a and shapes_b need at least one shape each");
  check_shape(poses_a, {-1, na, 4, 4}, "poses_a");
  check_finite(poses_a, "poses_a");
  const std::ptrdiff_t rows = poses_a.shape[0];
  const bool fixed = poses_b.ndim() == 3;  // shapes that do not move
  if (fixed) check_shape(poses_b, {nb, 4, 4}, "poses_b");
  else check_shape(poses_b, {rows, nb, 4, 4}, "poses_b");
  check_finite(poses_b, "poses_b");
  const auto a = poses_of(poses_a, rows * na, na, "poses_a"), b = poses_of(poses_b, fixed ? nb : rows * nb, fixed ? 0 : nb, "poses_b");
  BoxClearances out{std::vector<double>(rows), std::vector<long>(rows), std::vector<long>(rows)};
  shape_clearances(static_cast<int>(rows), a, shapes_a, b, shapes_b, fixed, out.d.data(), out.ia.data(), out.ib.data());
  return out;
}

}  // namespace coopsim
