#include <spacewarp/coords/convex_cage.h>

#include <spacewarp/coords/detail/convex_polyhedron.h>

namespace spacewarp {

void checkConvexCage(const Cage& cage, const char* method, double planarity) {
  (void)detail::buildConvexPolyhedron(cage, method, planarity);
}

void checkSimplicialConvexCage(const Cage& cage, const char* method, double planarity) {
  detail::checkSimplicial(detail::buildConvexPolyhedron(cage, method, planarity), cage, method);
}

}  // namespace spacewarp
