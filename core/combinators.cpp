#include <spacewarp/core/combinators.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/power_of_two_scale.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

AffineWarp::AffineWarp(const Mat4& m) : linear_(m), translation_(m[3]) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(m[c][r]))
        throw InvalidInput("affine matrix entry (" + std::to_string(r) + ", " + std::to_string(c) +
                           ") is not finite");
    }
  }
  if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0)
    throw InvalidInput("affine matrix: the last row must be (0, 0, 0, 1)");
  singular_ = isSingularJacobian(linear_);
  if (!singular_) linearInverse_ = detail::inverseScaled(linear_);  // entries of 1e300 too
}

std::optional<Vec3> AffineWarp::exactInverse(const Vec3& y) const {
  if (singular_) return std::nullopt;
  const Vec3 x = linearInverse_ * (y - translation_);
  // One step of refinement on the residual: the rounding of the inverse matrix is then
  // corrected to the accuracy of apply() itself.
  return x + linearInverse_ * (y - apply(x));
}

void ComposedWarp::append(std::shared_ptr<const Warp> stage) {
  if (!stage) throw InvalidInput("ComposedWarp: a warp is null");
  if (const auto* inner = dynamic_cast<const ComposedWarp*>(stage.get())) {
    // Its stages are flat already: one level of copying keeps the whole chain flat.
    stages_.insert(stages_.end(), inner->stages_.begin(), inner->stages_.end());
  } else {
    stages_.push_back(std::move(stage));
  }
}

ComposedWarp::ComposedWarp(std::shared_ptr<const Warp> first, std::shared_ptr<const Warp> second) {
  if (!first || !second) throw InvalidInput("ComposedWarp: a warp is null");
  append(std::move(first));
  append(std::move(second));
}

ComposedWarp::ComposedWarp(std::vector<std::shared_ptr<const Warp>> stages) {
  if (stages.size() < 2)
    throw InvalidInput("ComposedWarp: " + std::to_string(stages.size()) +
                       " stages, at least 2 are needed");
  for (std::size_t i = 0; i < stages.size(); ++i) {
    if (!stages[i]) throw InvalidInput("ComposedWarp: stage " + std::to_string(i) + " is null");
    append(std::move(stages[i]));
  }
}

Vec3 ComposedWarp::apply(const Vec3& x) const {
  Vec3 y = x;
  for (const auto& stage : stages_) y = stage->apply(y);
  return y;
}

Mat3 ComposedWarp::jacobian(const Vec3& x) const {
  // The nested form computes J_2(x_1) J_1(x) for the innermost pair first, then multiplies on
  // the left by each later stage: the same order as this loop.
  Vec3 y = x;
  Mat3 j(1.0);
  for (std::size_t i = 0; i < stages_.size(); ++i) {
    const Mat3 stage = stages_[i]->jacobian(y);
    j = i == 0 ? stage : stage * j;
    if (i + 1 < stages_.size()) y = stages_[i]->apply(y);
  }
  return j;
}

std::optional<Vec3> ComposedWarp::exactInverse(const Vec3& y) const {
  Vec3 x = y;
  for (auto stage = stages_.rbegin(); stage != stages_.rend(); ++stage) {
    const std::optional<Vec3> previous = (*stage)->exactInverse(x);
    if (!previous) return std::nullopt;
    x = *previous;
  }
  return x;
}

std::size_t ComposedWarp::batchGrain() const {
  std::size_t grain = stages_.front()->batchGrain();
  for (const auto& stage : stages_) grain = std::min(grain, stage->batchGrain());
  return grain;
}

UnmappedPoints ComposedWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                        std::size_t begin, std::size_t end) const {
  // Each report names the stage whose kernel made it, so that this stage explains it.
  UnmappedPoints unmapped;
  for (std::size_t i = 0; i < stages_.size(); ++i) {
    UnmappedPoints report =
        stages_[i]->applyRange(i == 0 ? in : std::span<const Vec3>(out), out, begin, end);
    if (report.count > 0 && !report.by) report.by = stages_[i].get();
    unmapped.merge(report);
  }
  return unmapped;
}

void IdentityWarp::save(ArchiveWriter& out) const { out.tag("identity"); }

std::shared_ptr<const IdentityWarp> IdentityWarp::load(ArchiveReader&) {
  return std::make_shared<const IdentityWarp>();
}

void AffineWarp::save(ArchiveWriter& out) const {
  out.tag("affine");
  Mat4 m(linear_);  // last row (0, 0, 0, 1)
  m[3] = glm::dvec4(translation_, 1.0);
  out.mat4(m);
}

std::shared_ptr<const AffineWarp> AffineWarp::load(ArchiveReader& in) {
  return std::make_shared<const AffineWarp>(in.mat4());
}

void ComposedWarp::save(ArchiveWriter& out) const {
  out.tag("compose");
  out.u64(stages_.size());
  for (const auto& stage : stages_) out.warp(*stage);
}

std::shared_ptr<const ComposedWarp> ComposedWarp::load(ArchiveReader& in) {
  const std::size_t start = in.position();
  const std::uint64_t count = in.u64();
  // Each stage takes at least its tag's length (8 bytes): a hostile count is refused before
  // anything is reserved.
  if (count < 2 || count > in.bytesLeft() / 8) {
    in.seek(start);
    in.fail("a composition of " + std::to_string(count) + " stages (at least 2, at most one per " +
            "8 bytes left)");
  }
  std::vector<std::shared_ptr<const Warp>> stages;
  stages.reserve(static_cast<std::size_t>(count));
  for (std::uint64_t i = 0; i < count; ++i) stages.push_back(in.warp());
  return std::make_shared<const ComposedWarp>(std::move(stages));
}

}  // namespace spacewarp
