#include <spacewarp/coords/convex_cage.h>

#include <spacewarp/coords/detail/convex_polyhedron.h>

namespace spacewarp {

void checkConvexCage(const Cage& cage, const char* method) {
  (void)detail::buildConvexPolyhedron(cage, method);
}

void checkSimplicialConvexCage(const Cage& cage, const char* method) {
  detail::checkSimplicial(detail::buildConvexPolyhedron(cage, method), cage, method);
}

}  // namespace spacewarp
