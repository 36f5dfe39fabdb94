#include <spacewarp/rbf/rbf_coordinates.h>

#include <cmath>
#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/rbf/detail/rbf_system.h>
#include <spacewarp/rbf/rbf_warp.h>

namespace spacewarp {

double RbfCoordinates::memoryEstimate(std::size_t centers, std::size_t fixed) {
  const double n = static_cast<double>(centers) + static_cast<double>(fixed);
  const double handles = static_cast<double>(centers);
  return sizeof(double) * (n * n + 4.0 * n * handles) + 4e6;
}

RbfCoordinates::RbfCoordinates(std::span<const Vec3> centers, const RbfOptions& options)
    : RbfCoordinates(centers, {}, options) {}

RbfCoordinates::RbfCoordinates(std::span<const Vec3> centers, std::span<const Vec3> fixed,
                               const RbfOptions& options)
    : options_(options),
      handles_(centers.begin(), centers.end()),
      fixed_(fixed.begin(), fixed.end()) {
  options_.progress = nullptr;  // the caller's, for this fit only: warps made later fit silently
  const std::string who = "RbfCoordinates";
  detail::checkMemory(
      memoryEstimate(centers.size(), fixed.size()),
      who + ": the solve for " + std::to_string(centers.size()) + " handles" +
          (fixed.empty() ? "" : " and " + std::to_string(fixed.size()) + " fixed centers"));
  const detail::RbfCenters c = detail::prepareRbfCenters(who, centers, nullptr, fixed, options);
  const detail::RbfSystem system(who, c.unique, options);
  centers_ = c.unique;
  const Eigen::Index n = static_cast<Eigen::Index>(c.unique.size());
  const Eigen::Index u = static_cast<Eigen::Index>(c.handleCenters);
  // One right-hand side per distinct handle center: its unit displacement.
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(n, u);
  for (Eigen::Index i = 0; i < u; ++i) d(i, i) = 1.0;
  Eigen::MatrixXd w, a;
  system.solve(d, w, a);
  const std::size_t handles = handles_.size();
  g_.resize(static_cast<std::size_t>(n) * handles);
  h_.resize(4 * handles);
  const Vec3& o = system.origin();
  const double len = system.length();
  for (std::size_t h = 0; h < handles; ++h) {
    const Eigen::Index col = static_cast<Eigen::Index>(c.handleColumn[h]);
    const double share = 1.0 / static_cast<double>(c.multiplicity[c.handleColumn[h]]);
    for (Eigen::Index j = 0; j < n; ++j)
      g_[static_cast<std::size_t>(j) * handles + h] = share * w(j, col);
    // a in the basis [1, (x − origin) / length] → coefficients of 1, x, y, z.
    double constant = a(0, col);
    for (int k = 0; k < 3; ++k) {
      const double lin = a(k + 1, col) / len;
      h_[(1 + k) * handles + h] = share * lin;
      constant -= lin * o[k];
    }
    h_[h] = share * constant;
  }
}

void RbfCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  const std::size_t m = handles_.size();
  const double* h = h_.data();
  for (std::size_t c = 0; c < m; ++c)
    row[c] = h[c] + x.x * h[m + c] + x.y * h[2 * m + c] + x.z * h[3 * m + c];
  for (std::size_t j = 0; j < centers_.size(); ++j) {
    const double phi = rbfKernelValue(options_, glm::length(x - centers_[j]));
    const double* g = g_.data() + j * m;
    for (std::size_t c = 0; c < m; ++c) row[c] += phi * g[c];
  }
}

bool RbfCoordinates::weightGradients(const Vec3& x, std::span<Vec3> out) const {
  const std::size_t m = handles_.size();
  if (out.size() != m) {
    throw InvalidInput("RbfCoordinates: the gradient output has " + std::to_string(out.size()) +
                       " entries but there are " + std::to_string(m) + " columns");
  }
  const double* h = h_.data();
  for (std::size_t c = 0; c < m; ++c) out[c] = Vec3(h[m + c], h[2 * m + c], h[3 * m + c]);
  for (std::size_t j = 0; j < centers_.size(); ++j) {
    const Vec3 v = x - centers_[j];
    const Vec3 grad = rbfKernelSlopeOverR(options_, glm::length(v)) * v;
    const double* g = g_.data() + j * m;
    for (std::size_t c = 0; c < m; ++c) out[c] += g[c] * grad;
  }
  return true;
}

std::shared_ptr<const Warp> RbfCoordinates::makeWarpFor(std::shared_ptr<const Coordinates>,
                                                        std::span<const Vec3> posed) const {
  return std::make_shared<RbfWarp>(handles_, posed, fixed_, options_);
}

void RbfCoordinates::save(ArchiveWriter& out) const {
  out.tag("rbf-coordinates");
  writeRbfOptions(out, options_);
  out.vec3s(handles_);
  out.vec3s(fixed_);
  out.vec3s(centers_);
  out.doubles(g_);
  out.doubles(h_);
}

std::shared_ptr<const RbfCoordinates> RbfCoordinates::load(ArchiveReader& in) {
  std::shared_ptr<RbfCoordinates> c(new RbfCoordinates());
  c->options_ = readRbfOptions(in);
  c->handles_ = in.vec3s();
  c->fixed_ = in.vec3s();
  c->centers_ = in.vec3s();
  c->g_ = in.doubles();
  c->h_ = in.doubles();
  const std::size_t handles = c->handles_.size();
  // centers_ are the distinct handles and fixed centers, at least one handle.
  if (handles == 0 || c->centers_.empty() || c->centers_.size() > handles + c->fixed_.size() ||
      c->g_.size() / c->centers_.size() != handles || c->g_.size() % c->centers_.size() != 0 ||
      c->h_.size() != 4 * handles)
    in.fail("RBF coordinates with inconsistent sizes (" + std::to_string(handles) + " handles, " +
            std::to_string(c->centers_.size()) + " centers, " + std::to_string(c->g_.size()) +
            " + " + std::to_string(c->h_.size()) + " coefficients)");
  bool finite = true;
  for (const auto* points : {&c->handles_, &c->fixed_, &c->centers_})
    for (const Vec3& p : *points) finite = finite && isFinite(p);
  for (const auto* values : {&c->g_, &c->h_})
    for (const double v : *values) finite = finite && std::isfinite(v);
  if (!finite) in.fail("RBF coordinates whose state is not finite");
  return c;
}

}  // namespace spacewarp
