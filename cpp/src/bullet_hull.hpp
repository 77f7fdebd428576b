// A convex hull for Bullet with its exact vertices (included by world.cpp and box_distance.cpp, the
// engine's Bullet files, only). Bullet's hull computer (optimizeConvexHull, initializePolyhedralFeatures)
// works on points rounded to a grid, so the vertices it gives back are off the input points by about
// 1e-6 of the hull's size: here each vertex is put back onto the input point it came from and the faces'
// planes and the edge directions are computed again from them, so that contacts and depths are those of
// the points given.
#pragma once

#include <BulletCollision/CollisionShapes/btConvexHullShape.h>
#include <BulletCollision/CollisionShapes/btConvexPolyhedron.h>

#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace coopsim {
namespace detail {

// The hull of `points` (m), margin zero, reduced to its vertices (the input points that are vertices);
// with `features`, its faces and edges for Bullet's polyhedral contact clipping and separating axes.
inline std::unique_ptr<btConvexHullShape> exact_hull_made(const std::vector<Eigen::Vector3d>& points, bool features) {
  btConvexHullShape probe;
  for (const Eigen::Vector3d& p : points) probe.addPoint(btVector3(p.x(), p.y(), p.z()), false);
  probe.setMargin(0.0);
  probe.initializePolyhedralFeatures();
  btConvexPolyhedron poly = *probe.getConvexPolyhedron();
  for (int v = 0; v < poly.m_vertices.size(); ++v) {  // back onto the nearest input point
    btScalar best = SIMD_INFINITY;
    btVector3 at = poly.m_vertices[v];
    for (const Eigen::Vector3d& p : points) {
      const btVector3 q(p.x(), p.y(), p.z());
      const btScalar d2 = (q - poly.m_vertices[v]).length2();
      if (d2 < best) {
        best = d2;
        at = q;
      }
    }
    poly.m_vertices[v] = at;
  }
  for (int f = 0; f < poly.m_faces.size(); ++f) {  // planes by Newell's method, facing as they did
    btFace& face = poly.m_faces[f];
    btVector3 n(0, 0, 0);
    const int k = face.m_indices.size();
    for (int i = 0; i < k; ++i) {
      const btVector3& a = poly.m_vertices[face.m_indices[i]];
      const btVector3& b = poly.m_vertices[face.m_indices[(i + 1) % k]];
      n += btVector3((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()),
                     (a.x() - b.x()) * (a.y() + b.y()));
    }
    if (n.length2() == 0) continue;
    n.normalize();
    if (n.dot(btVector3(face.m_plane[0], face.m_plane[1], face.m_plane[2])) < 0) n = -n;
    face.m_plane[0] = n.x();
    face.m_plane[1] = n.y();
    face.m_plane[2] = n.z();
    face.m_plane[3] = -n.dot(poly.m_vertices[face.m_indices[0]]);
  }
  poly.m_uniqueEdges.resize(0);
  poly.initialize();  // edges, centre and extents again
  auto hull = std::make_unique<btConvexHullShape>();
  for (int v = 0; v < poly.m_vertices.size(); ++v) hull->addPoint(poly.m_vertices[v], false);
  hull->setMargin(0.0);
  hull->recalcLocalAabb();
  if (features) hull->setPolyhedralFeatures(poly);
  return hull;
}

// exact_hull_made's result for these points, made once per process: a world built again (every run of a
// task, every reset of an environment) copies its hulls' vertices and faces instead of computing them again
// (Bullet's hull and its faces: about a million instructions for a link's mesh). Keyed by the points' bytes;
// the same points give the same hull bit for bit. At most kCached sets are kept (then the store starts over).
inline std::unique_ptr<btConvexHullShape> exact_hull(const std::vector<Eigen::Vector3d>& points, bool features) {
  constexpr size_t kCached = 512;
  struct Made {
    std::vector<btVector3> vertices;
    std::unique_ptr<btConvexPolyhedron> poly;  // with `features`
  };
  static std::mutex lock;
  static std::map<std::string, std::shared_ptr<const Made>> store;
  std::string key(points.size() * sizeof(Eigen::Vector3d) + 1, '\0');
  key[0] = features ? 1 : 0;
  if (!points.empty()) std::memcpy(&key[1], points.data(), points.size() * sizeof(Eigen::Vector3d));
  std::shared_ptr<const Made> made;
  {
    std::lock_guard<std::mutex> hold(lock);
    const auto it = store.find(key);
    if (it != store.end()) made = it->second;
  }
  if (!made) {
    const std::unique_ptr<btConvexHullShape> hull = exact_hull_made(points, features);
    auto m = std::make_shared<Made>();
    for (int v = 0; v < hull->getNumPoints(); ++v) m->vertices.push_back(hull->getUnscaledPoints()[v]);
    if (features) m->poly = std::make_unique<btConvexPolyhedron>(*hull->getConvexPolyhedron());
    made = m;
    std::lock_guard<std::mutex> hold(lock);
    if (store.size() >= kCached) store.clear();
    store.emplace(std::move(key), made);
  }
  auto hull = std::make_unique<btConvexHullShape>();
  for (const btVector3& v : made->vertices) hull->addPoint(v, false);
  hull->setMargin(0.0);
  hull->recalcLocalAabb();
  if (features) {
    btConvexPolyhedron copy = *made->poly;
    hull->setPolyhedralFeatures(copy);
  }
  return hull;
}

}  // namespace detail
}  // namespace coopsim
