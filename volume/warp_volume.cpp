#include <spacewarp/volume/warp_volume.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <vector>

#include <openvdb/tools/ChangeBackground.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/LevelSetRebuild.h>
#include <openvdb/tools/LevelSetTracker.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/volume/detail/warp_volume_parts.h>

namespace spacewarp {

namespace {

using openvdb::Coord;
using openvdb::CoordBBox;

Vec3 toVec3(const openvdb::Vec3d& v) { return {v[0], v[1], v[2]}; }
openvdb::Vec3d toVdb(const Vec3& v) { return {v.x, v.y, v.z}; }

std::int32_t floorDiv(std::int32_t a, std::int32_t b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

Coord roundToCoord(const Vec3& x) {
  return Coord(static_cast<std::int32_t>(std::floor(x.x + 0.5)),
               static_cast<std::int32_t>(std::floor(x.y + 0.5)),
               static_cast<std::int32_t>(std::floor(x.z + 0.5)));
}

bool coordLess(const Coord& a, const Coord& b) {
  if (a.x() != b.x()) return a.x() < b.x();
  if (a.y() != b.y()) return a.y() < b.y();
  return a.z() < b.z();
}

// The largest singular value of m (power iteration on mᵀ m).
double spectralNorm(const Mat3& m) {
  const Mat3 g = glm::transpose(m) * m;
  Vec3 v(1.0, 0.7, 0.4);
  double lambda = 0.0;
  for (int i = 0; i < 30; ++i) {
    const Vec3 w = g * v;
    const double n = glm::length(w);
    if (!(n > 0.0)) return 0.0;
    lambda = n / glm::length(v);
    v = w / n;
  }
  return std::sqrt(lambda);
}

// The linear (affine) voxel transform as world = a i + t, and its inverse.
struct IndexFrame {
  Mat3 a{1.0}, aInverse{1.0};
  Vec3 t{0.0};
  double voxelSize = 1.0;  // cube root of the voxel volume

  Vec3 toWorld(const Vec3& i) const { return a * i + t; }
  Vec3 toIndex(const Vec3& w) const { return aInverse * (w - t); }
};

IndexFrame indexFrame(const openvdb::GridBase& grid) {
  const openvdb::math::Transform& xform = grid.transform();
  if (!xform.isLinear()) {
    throw InvalidInput("warpVolume: grid '" + grid.getName() + "' has a non-linear transform (" +
                       xform.mapType() + "); only linear (affine) voxel transforms are supported");
  }
  IndexFrame f;
  f.t = toVec3(xform.indexToWorld(openvdb::Vec3d(0.0)));
  for (int c = 0; c < 3; ++c) {
    openvdb::Vec3d e(0.0);
    e[c] = 1.0;
    f.a[c] = toVec3(xform.indexToWorld(e)) - f.t;
  }
  const double det = glm::determinant(f.a);
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) {
    throw InvalidInput("warpVolume: grid '" + grid.getName() + "' has a singular transform");
  }
  f.aInverse = glm::inverse(f.a);
  f.voxelSize = std::cbrt(std::abs(det));
  return f;
}

// True when a voxel within `radius` (per axis) of x (index space) is active.
template <typename AccessorT>
bool nearActive(AccessorT& acc, const Vec3& x, double radius) {
  const Coord lo = roundToCoord(x - Vec3(radius));
  const Coord hi = roundToCoord(x + Vec3(radius));
  for (int i = lo.x(); i <= hi.x(); ++i)
    for (int j = lo.y(); j <= hi.y(); ++j)
      for (int k = lo.z(); k <= hi.z(); ++k)
        if (acc.isValueOn(Coord(i, j, k))) return true;
  return false;
}

// A cell of the input's index space: input voxels lo .. lo + size - 1 per axis, the cube
// [lo - 1/2, lo + size - 1/2]. Its image is approximated by the affine map
// F(center) + J (i - center) (index space to index space).
struct Cell {
  Coord lo;
  int size = 1;
  Vec3 center{0.0};  // input index space
  Vec3 image{0.0};   // F(center), output index space
  Mat3 jacobianInverse{1.0};
  Mat3 worldJacobianInverse{1.0};  // the same in world units
  double slack = 0.0;              // accepted distance outside the cell, input voxels
  CoordBBox outBox;                // output voxels that may have their preimage in the cell
  bool valid = false;              // false where the warp or its Jacobian is not usable
  bool beyondRange = false;        // its image lies beyond the index range a grid can hold
  bool poor = false;               // the affine model is off by more than half a voxel
};

// Output index coordinates stay within this, so that int32 voxel coordinates never overflow.
constexpr double kIndexLimit = 1e9;

struct CoordHash {
  std::size_t operator()(const Coord& k) const {
    return (static_cast<std::size_t>(static_cast<std::uint32_t>(k.x())) * 73856093u) ^
           (static_cast<std::size_t>(static_cast<std::uint32_t>(k.y())) * 19349663u) ^
           (static_cast<std::size_t>(static_cast<std::uint32_t>(k.z())) * 83492791u);
  }
};

// The key of corner d (bits: x, y, z) of a cell.
Coord cornerKey(const Cell& cell, int d) {
  return cell.lo +
         Coord((d & 1) * cell.size, ((d >> 1) & 1) * cell.size, ((d >> 2) & 1) * cell.size);
}

// Fills in a cell from the warp at its center and the images of its corners; returns whether
// the warp is rigid (Jᵀ J = I within 1e-9) at the center.
bool evaluateCell(const Warp& warp, const IndexFrame& frame,
                  const std::unordered_map<Coord, Vec3, CoordHash>& cornerImages, Cell& cell) {
  cell.center = Vec3(cell.lo.x(), cell.lo.y(), cell.lo.z()) + Vec3(0.5 * (cell.size - 1));
  const Vec3 centerWorld = frame.toWorld(cell.center);
  const Vec3 imageWorld = warp.apply(centerWorld);
  const Mat3 jWorld = warp.jacobian(centerWorld);
  const Mat3 g = glm::transpose(jWorld) * jWorld;
  double dev = 0.0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) dev = std::max(dev, std::abs(g[a][b] - (a == b ? 1.0 : 0.0)));
  const bool rigid = dev <= 1e-9;

  cell.image = frame.toIndex(imageWorld);
  const Mat3 j = frame.aInverse * jWorld * frame.a;
  if (!isFinite(cell.image) || isSingularJacobian(j)) return rigid;
  cell.jacobianInverse = glm::inverse(j);
  cell.worldJacobianInverse = frame.a * cell.jacobianInverse * frame.aInverse;
  // Deviation of the corners from the affine model, in output and input voxels.
  Vec3 lo = cell.image, hi = cell.image;
  double devOut = 0.0, devIn = 0.0;
  for (int d = 0; d < 8; ++d) {
    const Coord key = cornerKey(cell, d);
    const Vec3& p = cornerImages.at(key);
    if (!isFinite(p)) return rigid;
    const Vec3 corner = Vec3(key.x(), key.y(), key.z()) - Vec3(0.5);
    const Vec3 err = p - (cell.image + j * (corner - cell.center));
    devOut = std::max(devOut, maxAbs(err));
    devIn = std::max(devIn, maxAbs(cell.jacobianInverse * err));
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  cell.poor = !(devIn <= 0.5 && devOut <= 0.5 * cell.size + 0.5);
  // Single voxels whose model stays poor (the warp is not smooth at the voxel scale) get a
  // bounded margin: their images are then approximate.
  // The model puts a preimage at most about devIn from where it is, and an image at most
  // devOut: twice that (and a little more) keeps the region complete.
  cell.slack = 0.05 + 2.0 * devIn;
  double grow = 0.5 + 2.0 * devOut;
  if (cell.poor) {
    cell.slack = std::min(cell.slack, 2.0);
    grow = std::min(grow, 2.0);
  }
  if (!(maxAbs(lo) < kIndexLimit) || !(maxAbs(hi) < kIndexLimit)) {
    cell.beyondRange = true;
    return rigid;
  }
  cell.outBox = CoordBBox(Coord(static_cast<std::int32_t>(std::ceil(lo.x - grow)),
                                static_cast<std::int32_t>(std::ceil(lo.y - grow)),
                                static_cast<std::int32_t>(std::ceil(lo.z - grow))),
                          Coord(static_cast<std::int32_t>(std::floor(hi.x + grow)),
                                static_cast<std::int32_t>(std::floor(hi.y + grow)),
                                static_cast<std::int32_t>(std::floor(hi.z + grow))));
  cell.valid = true;
  return rigid;
}

// The warp replaced by the trilinear interpolant of its displacement, sampled at the nodes
// k h (input index space, h = `spacing` voxels) of every lattice cell near the given coarse
// cells. Points outside the sampled lattice use the exact warp.
class CachedWarp final : public Warp {
 public:
  CachedWarp(const Warp& exact, const IndexFrame& frame, double spacing,
             const std::vector<Coord>& cellKeys, int cellSize)
      : exact_(exact), frame_(frame), h_(spacing), nodes_(openvdb::Vec3d(0.0)) {
    // Nodes of the lattice cells that overlap the coarse cells widened by 2 voxels + h.
    openvdb::MaskTree mask(false);
    const double margin = 2.0 + h_;
    for (const Coord& k : cellKeys) {
      const Vec3 lo = Vec3(k.x(), k.y(), k.z()) * double(cellSize) - Vec3(0.5 + margin);
      const Vec3 hi = lo + Vec3(double(cellSize) + 2.0 * margin);
      const CoordBBox box(Coord(static_cast<std::int32_t>(std::floor(lo.x / h_)),
                                static_cast<std::int32_t>(std::floor(lo.y / h_)),
                                static_cast<std::int32_t>(std::floor(lo.z / h_))),
                          Coord(static_cast<std::int32_t>(std::ceil(hi.x / h_)),
                                static_cast<std::int32_t>(std::ceil(hi.y / h_)),
                                static_cast<std::int32_t>(std::ceil(hi.z / h_))));
      mask.sparseFill(box, true, true);
    }
    mask.voxelizeActiveTiles();
    std::vector<Coord> keys;
    keys.reserve(static_cast<std::size_t>(mask.activeVoxelCount()));
    for (auto it = mask.cbeginValueOn(); it; ++it) keys.push_back(it.getCoord());
    std::vector<Vec3> world(keys.size()), images(keys.size());
    for (std::size_t i = 0; i < keys.size(); ++i) world[i] = nodeWorld(keys[i]);
    exact_.applyBatch(world, images);
    openvdb::tree::ValueAccessor<openvdb::Vec3DTree> acc(nodes_);
    for (std::size_t i = 0; i < keys.size(); ++i) {
      const Vec3 d = images[i] - world[i];
      acc.setValueOn(keys[i], openvdb::Vec3d(d.x, d.y, d.z));
    }
    // The deviation from the exact warp at the center of every complete lattice cell.
    std::vector<Vec3> centers;
    centers.reserve(keys.size());
    for (const Coord& k : keys) {
      const Vec3 center = nodeWorld(k) + frame_.a * Vec3(0.5 * h_);
      if (sampled(center)) centers.push_back(center);
    }
    std::vector<Vec3> exactImages(centers.size());
    exact_.applyBatch(centers, exactImages);
    for (std::size_t i = 0; i < centers.size(); ++i)
      error_ = std::max(error_, glm::length(apply(centers[i]) - exactImages[i]));
  }

  Vec3 apply(const Vec3& x) const override {
    Vec3 d[8], frac;
    if (!gather(x, d, frac)) return exact_.apply(x);
    return x + trilinear(d, frac);
  }

  Mat3 jacobian(const Vec3& x) const override {
    Vec3 d[8], f;
    if (!gather(x, d, f)) return exact_.jacobian(x);
    // ∂(displacement)/∂k along each lattice axis, then the chain rule to world units.
    const Vec3 dx = (d[1] - d[0]) * (1 - f.y) * (1 - f.z) + (d[3] - d[2]) * f.y * (1 - f.z) +
                    (d[5] - d[4]) * (1 - f.y) * f.z + (d[7] - d[6]) * f.y * f.z;
    const Vec3 dy = (d[2] - d[0]) * (1 - f.x) * (1 - f.z) + (d[3] - d[1]) * f.x * (1 - f.z) +
                    (d[6] - d[4]) * (1 - f.x) * f.z + (d[7] - d[5]) * f.x * f.z;
    const Vec3 dz = (d[4] - d[0]) * (1 - f.x) * (1 - f.y) + (d[5] - d[1]) * f.x * (1 - f.y) +
                    (d[6] - d[2]) * (1 - f.x) * f.y + (d[7] - d[3]) * f.x * f.y;
    return Mat3(1.0) + Mat3(dx, dy, dz) * (frame_.aInverse / h_);
  }

  /// Largest deviation from the exact warp at the lattice cell centers, world units.
  double error() const { return error_; }

 private:
  Vec3 nodeWorld(const Coord& k) const { return frame_.toWorld(Vec3(k.x(), k.y(), k.z()) * h_); }

  bool sampled(const Vec3& x) const {
    Vec3 d[8], f;
    return gather(x, d, f);
  }

  // The displacements at the 8 nodes around x (bit 0: +x, 1: +y, 2: +z) and x's fraction
  // in that lattice cell; false if x is outside the sampled lattice.
  bool gather(const Vec3& x, Vec3 (&d)[8], Vec3& frac) const {
    const Vec3 k = frame_.toIndex(x) / h_;
    if (!(maxAbs(k) < 1e9)) return false;
    const Vec3 base = glm::floor(k);
    frac = k - base;
    const Coord b(static_cast<std::int32_t>(base.x), static_cast<std::int32_t>(base.y),
                  static_cast<std::int32_t>(base.z));
    openvdb::tree::ValueAccessor<const openvdb::Vec3DTree, false> acc(nodes_);
    for (int n = 0; n < 8; ++n) {
      openvdb::Vec3d v;
      if (!acc.probeValue(b + Coord(n & 1, (n >> 1) & 1, (n >> 2) & 1), v)) return false;
      d[n] = Vec3(v[0], v[1], v[2]);
    }
    return true;
  }

  static Vec3 trilinear(const Vec3 (&d)[8], const Vec3& f) {
    const Vec3 x00 = d[0] + (d[1] - d[0]) * f.x, x10 = d[2] + (d[3] - d[2]) * f.x;
    const Vec3 x01 = d[4] + (d[5] - d[4]) * f.x, x11 = d[6] + (d[7] - d[6]) * f.x;
    const Vec3 y0 = x00 + (x10 - x00) * f.y, y1 = x01 + (x11 - x01) * f.y;
    return y0 + (y1 - y0) * f.z;
  }

  const Warp& exact_;
  IndexFrame frame_;
  double h_;
  openvdb::Vec3DTree nodes_;
  double error_ = 0.0;
};

// What happens to the values of a vector grid, VectorTransform resolved for its VecType.
enum class VectorRule { Keep, Push, Covariant, CovariantNormalize, Normal, Position };

VectorRule vectorRule(VectorTransform mode, openvdb::VecType type) {
  switch (mode) {
    case VectorTransform::Push:
      return VectorRule::Push;
    case VectorTransform::Normal:
      return VectorRule::Normal;
    case VectorTransform::Keep:
      return VectorRule::Keep;
    case VectorTransform::Auto:
      break;
  }
  switch (type) {
    case openvdb::VEC_COVARIANT:
      return VectorRule::Covariant;
    case openvdb::VEC_COVARIANT_NORMALIZE:
      return VectorRule::CovariantNormalize;
    case openvdb::VEC_CONTRAVARIANT_ABSOLUTE:
      return VectorRule::Position;
    default:  // contravariant relative, and invariant: what files that say nothing hold
      return VectorRule::Push;
  }
}

const char* describe(VectorRule rule) {
  switch (rule) {
    case VectorRule::Keep:
      return "unchanged";
    case VectorRule::Push:
      return "J v";
    case VectorRule::Covariant:
      return "J^-T v";
    case VectorRule::CovariantNormalize:
      return "J^-T v normalised";
    case VectorRule::Normal:
      return "J^-T v, length kept";
    case VectorRule::Position:
      return "warp(v)";
  }
  return "";
}

// The vector v (world units, or index units when `local`) of the input at x (world) carried to
// the image of x; false when it cannot be (singular J for the covariant rules, not finite).
bool transformVector(const Warp& warp, const IndexFrame& frame, VectorRule rule, bool local,
                     const Vec3& x, Vec3& v) {
  if (rule == VectorRule::Keep) return true;
  if (rule == VectorRule::Position) {
    const Vec3 image = warp.apply(local ? frame.toWorld(v) : v);
    v = local ? frame.toIndex(image) : image;
    return isFinite(v);
  }
  Mat3 j = warp.jacobian(x);
  if (local) j = frame.aInverse * j * frame.a;
  if (rule == VectorRule::Push) {
    v = j * v;
    return isFinite(v);
  }
  if (isSingularJacobian(j)) return false;
  const Vec3 w = glm::transpose(glm::inverse(j)) * v;
  const double length = glm::length(w);
  if (rule == VectorRule::Covariant || !(length > 0.0)) {
    v = w;
  } else {
    v = w * ((rule == VectorRule::Normal ? glm::length(v) : 1.0) / length);
  }
  return isFinite(v);
}

// Throws InvalidInput for options out of their ranges.
void validate(const WarpVolumeOptions& options) {
  if (!(options.cacheSpacing >= 0.0) || !std::isfinite(options.cacheSpacing)) {
    throw InvalidInput("warpVolume: cacheSpacing must be finite and >= 0, got " +
                       std::to_string(options.cacheSpacing));
  }
  if (options.normCount < 0) {
    throw InvalidInput("warpVolume: normCount must be >= 0, got " +
                       std::to_string(options.normCount));
  }
  if (options.seedSpacing < 1) {
    throw InvalidInput("warpVolume: seedSpacing must be at least 1 voxel, got " +
                       std::to_string(options.seedSpacing));
  }
  if (!(options.maxCandidateVoxels > 0.0)) {
    throw InvalidInput("warpVolume: maxCandidateVoxels must be > 0");
  }
  if (options.inverse.maxIterations < 1 || !(options.inverse.tolerance > 0.0)) {
    throw InvalidInput("warpVolume: inverse.maxIterations must be >= 1 and inverse.tolerance > 0");
  }
}

// The (leaf origin, cell) pairs of the output leaves that a cell may reach.
using LeafCellPair = std::pair<Coord, std::uint32_t>;

// What the stages of resampleGrid() share: the input, the warp (exact or cached), the seeding
// cells and which of them may reach which output leaf.
template <typename GridT>
struct GridPlan {
  using TreeT = typename GridT::TreeType;
  using ValueT = typename GridT::ValueType;
  using LeafT = typename TreeT::LeafNodeType;
  static constexpr bool kScalar = std::is_floating_point_v<ValueT>;

  GridPlan(const GridT& grid, const WarpVolumeOptions& opts)
      : in(grid), options(opts), frame(indexFrame(grid)) {}

  const GridT& in;
  const WarpVolumeOptions& options;
  IndexFrame frame;
  bool levelSet = false;
  bool conserveMass = false;
  double voxelVolume = 1.0;
  std::unique_ptr<CachedWarp> cached;  // set with options.cacheSpacing
  const Warp* warp = nullptr;          // *cached, or the caller's warp
  std::vector<Cell> cells;
  bool rigid = true;                         // Jᵀ J = I at every cell center
  std::vector<LeafCellPair> pairs;           // sorted by leaf, then cell
  std::vector<std::size_t> groupStart;       // pairs[groupStart[g] .. groupStart[g+1]): leaf g
  const detail::VolumePart* part = nullptr;  // the part of the output to solve; null: all

  std::size_t groups() const { return groupStart.size() - 1; }
  const TreeT& tree() const { return in.tree(); }
};

// The coarse cells (edge c voxels) that hold active voxels or tiles, sorted.
template <typename TreeT>
std::vector<Coord> activeCellKeys(const TreeT& inTree, int c) {
  using LeafT = typename TreeT::LeafNodeType;
  std::vector<Coord> cellKeys;
  std::vector<const LeafT*> leaves;
  leaves.reserve(inTree.leafCount());
  for (auto it = inTree.cbeginLeaf(); it; ++it) leaves.push_back(it.getLeaf());
  std::vector<std::vector<Coord>> perLeaf(leaves.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.size(), 16),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t l = r.begin(); l != r.end(); ++l) {
                        std::vector<Coord>& keys = perLeaf[l];
                        for (auto v = leaves[l]->cbeginValueOn(); v; ++v) {
                          const Coord ijk = v.getCoord();
                          keys.emplace_back(floorDiv(ijk.x(), c), floorDiv(ijk.y(), c),
                                            floorDiv(ijk.z(), c));
                        }
                        std::sort(keys.begin(), keys.end(), coordLess);
                        keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
                      }
                    });
  for (const auto& keys : perLeaf) cellKeys.insert(cellKeys.end(), keys.begin(), keys.end());
  typename TreeT::ValueOnCIter tiles = inTree.cbeginValueOn();
  tiles.setMaxDepth(TreeT::ValueOnCIter::LEAF_DEPTH - 1);
  for (; tiles; ++tiles) {
    if (!tiles.isTileValue()) continue;
    const CoordBBox box = tiles.getBoundingBox();
    const Coord lo(floorDiv(box.min().x(), c), floorDiv(box.min().y(), c),
                   floorDiv(box.min().z(), c));
    const Coord hi(floorDiv(box.max().x(), c), floorDiv(box.max().y(), c),
                   floorDiv(box.max().z(), c));
    for (int x = lo.x(); x <= hi.x(); ++x)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int z = lo.z(); z <= hi.z(); ++z) cellKeys.emplace_back(x, y, z);
  }
  std::sort(cellKeys.begin(), cellKeys.end(), coordLess);
  cellKeys.erase(std::unique(cellKeys.begin(), cellKeys.end()), cellKeys.end());
  return cellKeys;
}

using CornerImages = std::unordered_map<Coord, Vec3, CoordHash>;  // key m: index position m - 1/2

// Adds the images of the corners of the cells that are not known yet, one batch.
void addCornerImages(const Warp& warp, const IndexFrame& frame, const std::vector<Cell>& batch,
                     CornerImages& cornerImages) {
  std::vector<Coord> need;
  for (const Cell& cell : batch)
    for (int d = 0; d < 8; ++d) {
      const Coord key = cornerKey(cell, d);
      if (cornerImages.find(key) == cornerImages.end()) need.push_back(key);
    }
  std::sort(need.begin(), need.end(), coordLess);
  need.erase(std::unique(need.begin(), need.end()), need.end());
  std::vector<Vec3> world(need.size()), images(need.size());
  for (std::size_t i = 0; i < need.size(); ++i)
    world[i] = frame.toWorld(Vec3(need[i].x(), need[i].y(), need[i].z()) - Vec3(0.5));
  warp.applyBatch(world, images);
  for (std::size_t i = 0; i < need.size(); ++i)
    cornerImages.emplace(need[i], frame.toIndex(images[i]));
}

// Appends the children of a cell (half its size; single voxels for odd sizes) that hold active
// values.
template <typename AccessorT>
void splitCell(const Cell& cell, AccessorT& acc, std::vector<Cell>& next) {
  const int s = cell.size % 2 == 0 ? cell.size / 2 : 1;
  for (int x = 0; x < cell.size; x += s)
    for (int y = 0; y < cell.size; y += s)
      for (int z = 0; z < cell.size; z += s) {
        Cell child;
        child.lo = cell.lo + Coord(x, y, z);
        child.size = s;
        bool active = false;
        const CoordBBox box(child.lo, child.lo + Coord(s - 1));
        for (auto ijk = box.begin(); ijk && !active; ++ijk) active = acc.isValueOn(*ijk);
        if (active) next.push_back(child);
      }
}

// Stage 2. Forward images: the warp at every cell corner and center, the Jacobian at centers.
// Cells whose affine model is poor (the corners deviate from it by more than half a voxel) are
// split until it is good or they are single voxels.
template <typename GridT>
void buildCells(GridPlan<GridT>& plan, const std::vector<Coord>& cellKeys, int c) {
  CornerImages cornerImages;
  std::vector<Cell> pending(cellKeys.size());
  for (std::size_t i = 0; i < cellKeys.size(); ++i) {
    pending[i].lo = Coord(cellKeys[i].x() * c, cellKeys[i].y() * c, cellKeys[i].z() * c);
    pending[i].size = c;
  }
  while (!pending.empty()) {
    addCornerImages(*plan.warp, plan.frame, pending, cornerImages);
    std::vector<char> cellRigid(pending.size(), 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pending.size(), 64),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i)
                          cellRigid[i] =
                              evaluateCell(*plan.warp, plan.frame, cornerImages, pending[i]);
                      });
    plan.rigid = plan.rigid &&
                 std::all_of(cellRigid.begin(), cellRigid.end(), [](char x) { return x != 0; });
    std::vector<Cell> next;
    openvdb::tree::ValueAccessor<const typename GridPlan<GridT>::TreeT> acc(plan.tree());
    for (const Cell& cell : pending) {
      if (!cell.poor || cell.size == 1) {
        plan.cells.push_back(cell);
        continue;
      }
      splitCell(cell, acc, next);
    }
    pending = std::move(next);
  }
}

// Throws for cells whose image cannot be stored; counts the active voxels of cells where the
// warp is not usable.
template <typename GridT>
void checkCells(const GridPlan<GridT>& plan, WarpVolumeReport& report) {
  openvdb::tree::ValueAccessor<const typename GridPlan<GridT>::TreeT> acc(plan.tree());
  for (const Cell& cell : plan.cells) {
    if (cell.beyondRange) {
      // Not a failure of the warp: the result cannot be stored at this voxel size.
      const Vec3 at = plan.frame.toWorld(cell.center);
      std::ostringstream m;
      m << std::setprecision(6) << "warpVolume: grid '" << plan.in.getName()
        << "': the warp sends the voxels near world (" << at.x << ", " << at.y << ", " << at.z
        << ") beyond index " << kIndexLimit << " of the output grid, more than its 32-bit voxel "
        << "coordinates hold at this voxel size; use larger voxels or move the grid";
      throw InvalidInput(m.str());
    }
    if (cell.valid) continue;
    const CoordBBox box(cell.lo, cell.lo + Coord(cell.size - 1));
    for (auto ijk = box.begin(); ijk; ++ijk)
      if (acc.isValueOn(*ijk)) ++report.unmappedVoxels;
  }
}

// The work and memory below follow the images of the cells: refuse before allocating when a
// warp that is not smooth at the voxel scale spreads them over far more than the bound.
template <typename GridT>
void checkCandidateBound(const GridPlan<GridT>& plan, const WarpVolumeReport& report) {
  double candidates = 0.0, worst = 0.0;
  const Cell* worstCell = nullptr;
  for (const Cell& cell : plan.cells) {
    if (!cell.valid) continue;
    const Vec3 extent = Vec3(cell.outBox.max().x(), cell.outBox.max().y(), cell.outBox.max().z()) -
                        Vec3(cell.outBox.min().x(), cell.outBox.min().y(), cell.outBox.min().z()) +
                        Vec3(1.0);  // in double: int32 extents may overflow
    candidates += extent.x * extent.y * extent.z;
    const double stretch = maxAbs(extent) / cell.size;
    if (stretch > worst) {
      worst = stretch;
      worstCell = &cell;
    }
  }
  if (candidates > plan.options.maxCandidateVoxels && worstCell) {
    const Vec3 at = plan.frame.toWorld(worstCell->center);
    std::ostringstream m;
    m << std::setprecision(3) << "warpVolume: grid '" << plan.in.getName()
      << "': the warp is not smooth at the scale of its voxels: it spreads the "
      << report.inputActiveVoxels << " active voxels over about " << candidates
      << " output voxels (more than maxCandidateVoxels = " << plan.options.maxCandidateVoxels
      << "); near world (" << at.x << ", " << at.y << ", " << at.z << ") one voxel's image spans "
      << worst << " voxels. Use finer voxels or a gentler warp there";
    throw InvalidInput(m.str());
  }
}

// Stage 3. Which cells may reach which output leaf: (leaf origin, cell) pairs, sorted, and
// where each leaf's pairs start.
template <typename GridT>
void pairCellsWithLeaves(GridPlan<GridT>& plan) {
  using LeafT = typename GridPlan<GridT>::LeafT;
  const std::vector<Cell>& cells = plan.cells;
  std::vector<LeafCellPair>& pairs = plan.pairs;
  std::vector<std::vector<LeafCellPair>> perCell(cells.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cells.size(), 64),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        if (!cells[i].valid) continue;
                        const CoordBBox& b = cells[i].outBox;
                        const Coord lo = b.min() & ~(LeafT::DIM - 1);
                        const Coord hi = b.max() & ~(LeafT::DIM - 1);
                        for (int x = lo.x(); x <= hi.x(); x += LeafT::DIM)
                          for (int y = lo.y(); y <= hi.y(); y += LeafT::DIM)
                            for (int z = lo.z(); z <= hi.z(); z += LeafT::DIM)
                              perCell[i].emplace_back(Coord(x, y, z),
                                                      static_cast<std::uint32_t>(i));
                      }
                    });
  for (const auto& p : perCell)
    for (const LeafCellPair& pair : p)
      if (!plan.part || plan.part->outputBox.isInside(pair.first)) pairs.push_back(pair);
  std::sort(pairs.begin(), pairs.end(), [](const LeafCellPair& a, const LeafCellPair& b) {
    if (a.first != b.first) return coordLess(a.first, b.first);
    return a.second < b.second;
  });
  for (std::size_t i = 0; i < pairs.size(); ++i)
    if (i == 0 || pairs[i].first != pairs[i - 1].first) plan.groupStart.push_back(i);
  plan.groupStart.push_back(pairs.size());
}

// Stages 1 to 3: the plan of a grid, with the input's measures in the report.
template <typename GridT>
GridPlan<GridT> makePlan(const Warp& exactWarp, const GridT& in, const WarpVolumeOptions& options,
                         WarpVolumeReport& report, const detail::VolumePart* part = nullptr) {
  using TreeT = typename GridPlan<GridT>::TreeT;
  constexpr bool kScalar = GridPlan<GridT>::kScalar;
  GridPlan<GridT> plan(in, options);
  plan.part = part;
  plan.levelSet = kScalar && in.getGridClass() == openvdb::GRID_LEVEL_SET;
  if (plan.levelSet && !in.transform().hasUniformScale()) {
    throw InvalidInput("warpVolume: level set '" + in.getName() +
                       "' has non-cubic voxels; level sets need a uniform voxel scale");
  }
  plan.conserveMass = kScalar && !plan.levelSet && options.conserveMass;
  const TreeT& inTree = in.tree();
  const int c = options.seedSpacing;

  report.inputActiveVoxels = static_cast<std::size_t>(in.activeVoxelCount());
  plan.voxelVolume = std::abs(glm::determinant(plan.frame.a));
  if constexpr (kScalar) {
    if (!plan.levelSet) {
      double mass = 0.0;
      for (auto it = inTree.cbeginValueOn(); it; ++it)
        mass += static_cast<double>(*it) * static_cast<double>(it.getVoxelCount());
      report.massBefore = mass * plan.voxelVolume;
    }
    if (plan.levelSet) {
      report.halfWidth = static_cast<double>(in.background()) / plan.frame.voxelSize;
    }
  }

  // 1. The coarse cells that hold active voxels or tiles.
  const std::vector<Coord> cellKeys = part ? part->cellKeys : activeCellKeys(inTree, c);
  // The warp itself, or its displacement sampled on a lattice over the cells.
  if (options.cacheSpacing > 0.0) {
    plan.cached =
        std::make_unique<CachedWarp>(exactWarp, plan.frame, options.cacheSpacing, cellKeys, c);
    report.cacheError = plan.cached->error();
  }
  plan.warp = plan.cached ? static_cast<const Warp*>(plan.cached.get()) : &exactWarp;
  buildCells(plan, cellKeys, c);
  if (part) plan.rigid = part->rigid;  // the whole grid's, not the part's cells'
  checkCells(plan, report);
  checkCandidateBound(plan, report);
  pairCellsWithLeaves(plan);
  return plan;
}

// A voxel whose first solve failed: its offset in the leaf and its seeding cell.
struct Retry {
  int n;
  std::uint32_t cell;
};

// What the solves of one output leaf produced.
template <typename LeafT>
struct LeafResult {
  std::unique_ptr<LeafT> leaf;
  std::vector<Retry> retries;  // voxels where the first solve failed
  std::size_t solved = 0, failures = 0, vectorFailures = 0, iterations = 0;
  std::size_t haloMisses = 0;  // VolumePart::validInput: stencils that left the known input
  int maxIterations = 0;
  double mass = 0.0;
  // conserveMass: the range of |det J| the densities were divided by, and the voxels left
  // out because it was 0 or not finite.
  double minVolumeChange = std::numeric_limits<double>::infinity();
  double maxVolumeChange = 0.0;
  std::size_t degenerateVolumeChanges = 0;
};

// Samples the input at the preimage of an output voxel and stores the value, transformed as
// the grid's kind asks (mass, distance, vector rules).
template <typename GridT>
class VoxelSampler {
 public:
  using TreeT = typename GridPlan<GridT>::TreeT;
  using ValueT = typename GridPlan<GridT>::ValueT;
  using LeafT = typename GridPlan<GridT>::LeafT;
  using Accessor = openvdb::tree::ValueAccessor<const TreeT>;

  explicit VoxelSampler(const GridPlan<GridT>& plan)
      : plan_(plan),
        background_(plan.in.background()),
        toDistance_(plan.levelSet && plan.options.redistance == LevelSetRedistance::Normalize &&
                    !plan.rigid),
        vectors_(vectorRule(plan.options.vectors, plan.in.getVectorType())),
        localVectors_(!plan.in.isInWorldSpace()) {}

  VectorRule vectors() const { return vectors_; }

  // Voxel n of the leaf at `origin` takes the input's value at its preimage x (world), found
  // from the cell `seedCell`; nothing is stored where x is not in an active input voxel.
  void settle(Accessor& acc, LeafResult<LeafT>& out, const Coord& origin, int n, const Vec3& x,
              std::uint32_t seedCell) const {
    const Vec3 xIndex = plan_.frame.toIndex(x);
    if (plan_.part && plan_.part->validInput) {
      // The samplers and the gradient reach at most 2 voxels from the nearest voxel.
      const Coord at = roundToCoord(xIndex);
      if (!plan_.part->validInput->isInside(CoordBBox(at.offsetBy(-2), at.offsetBy(2)))) {
        ++out.haloMisses;
        return;
      }
    }
    if (!acc.isValueOn(roundToCoord(xIndex))) return;
    ValueT value;
    if (plan_.options.sampler == VolumeSampler::Triquadratic) {
      value = openvdb::tools::QuadraticSampler::sample(acc, toVdb(xIndex));
    } else {
      value = openvdb::tools::BoxSampler::sample(acc, toVdb(xIndex));
    }
    if constexpr (GridPlan<GridT>::kScalar) {
      if (!scalar(acc, out, x, xIndex, seedCell, value)) return;
    } else {
      Vec3 v(value[0], value[1], value[2]);
      if (!transformVector(*plan_.warp, plan_.frame, vectors_, localVectors_, x, v)) {
        ++out.vectorFailures;
        return;
      }
      value = ValueT(static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z));
    }
    if (!out.leaf) out.leaf = std::make_unique<LeafT>(origin, background_, false);
    out.leaf->setValueOn(static_cast<openvdb::Index>(n), value);
  }

 private:
  // Scalar grids: the value scaled for mass conservation or towards distances; false (and a
  // failure counted) where the Jacobian's determinant is unusable for mass conservation.
  bool scalar(Accessor& acc, LeafResult<LeafT>& out, const Vec3& x, const Vec3& xIndex,
              std::uint32_t seedCell, ValueT& value) const {
    if (plan_.conserveMass) {
      const double det = std::abs(glm::determinant(plan_.warp->jacobian(x)));
      if (!(det > 0.0) || !std::isfinite(det)) {
        ++out.failures;
        ++out.degenerateVolumeChanges;
        return false;
      }
      out.minVolumeChange = std::min(out.minVolumeChange, det);
      out.maxVolumeChange = std::max(out.maxVolumeChange, det);
      value = static_cast<ValueT>(static_cast<double>(value) / det);
    }
    if (toDistance_) {
      // ψ = φ∘F⁻¹ has gradient J⁻ᵀ∇φ: dividing by its relative length makes the
      // resampled values distances to first order, so the band is trimmed right.
      const Coord i = roundToCoord(xIndex);
      const Vec3 g(
          double(acc.getValue(i.offsetBy(1, 0, 0))) - double(acc.getValue(i.offsetBy(-1, 0, 0))),
          double(acc.getValue(i.offsetBy(0, 1, 0))) - double(acc.getValue(i.offsetBy(0, -1, 0))),
          double(acc.getValue(i.offsetBy(0, 0, 1))) - double(acc.getValue(i.offsetBy(0, 0, -1))));
      const double warped = glm::length(glm::transpose(plan_.cells[seedCell].jacobianInverse) * g);
      const double plain = glm::length(g);
      if (warped > 0.0 && plain > 0.0) {
        value =
            static_cast<ValueT>(static_cast<double>(value) * std::clamp(plain / warped, 0.2, 5.0));
      }
    }
    if (!plan_.levelSet) out.mass += static_cast<double>(value);
    return true;
  }

  const GridPlan<GridT>& plan_;
  ValueT background_;
  bool toDistance_;
  VectorRule vectors_;
  bool localVectors_;
};

// The seeds of the voxels of output leaf g: for each voxel the cell whose affine model puts its
// preimage least far outside the cell (best[n] = how far, infinity for none), and that point.
template <typename GridT>
void seedLeaf(const GridPlan<GridT>& plan, std::size_t g, std::vector<double>& best,
              std::vector<Vec3>& seeds, std::vector<std::uint32_t>& seedCellOf) {
  using LeafT = typename GridPlan<GridT>::LeafT;
  const Coord origin = plan.pairs[plan.groupStart[g]].first;
  const CoordBBox leafBox = CoordBBox::createCube(origin, LeafT::DIM);
  std::fill(best.begin(), best.end(), std::numeric_limits<double>::infinity());
  for (std::size_t p = plan.groupStart[g]; p < plan.groupStart[g + 1]; ++p) {
    const Cell& cell = plan.cells[plan.pairs[p].second];
    CoordBBox box = cell.outBox;
    box.intersect(leafBox);
    if (box.empty()) continue;
    const double half = 0.5 * cell.size;
    const Vec3 stepZ = cell.jacobianInverse[2];
    for (int x = box.min().x(); x <= box.max().x(); ++x)
      for (int y = box.min().y(); y <= box.max().y(); ++y) {
        Vec3 offset = cell.jacobianInverse * (Vec3(x, y, box.min().z()) - cell.image);
        for (int z = box.min().z(); z <= box.max().z(); ++z, offset += stepZ) {
          const double outside = maxAbs(offset) - half;
          if (outside > cell.slack) continue;
          const int n = static_cast<int>(LeafT::coordToOffset(Coord(x, y, z)));
          if (outside < best[n]) {
            best[n] = outside;
            seeds[n] = cell.center + offset;
            seedCellOf[n] = plan.pairs[p].second;
          }
        }
      }
  }
}

// Stage 4. Every output leaf: seed, solve (chord and Newton steps from the seed), test, sample.
// Voxels whose solve fails are left in their leaf's retries.
template <typename GridT>
void solveLeaves(const GridPlan<GridT>& plan, const VoxelSampler<GridT>& sampler,
                 const InverseOptions& firstSolve,
                 std::vector<LeafResult<typename GridPlan<GridT>::LeafT>>& leafResults,
                 ProgressTracker& tracker) {
  using LeafT = typename GridPlan<GridT>::LeafT;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, plan.groups(), 4),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      typename VoxelSampler<GridT>::Accessor acc(plan.tree());
                      constexpr int kSize = static_cast<int>(LeafT::SIZE);
                      std::vector<double> best(kSize);
                      std::vector<Vec3> seeds(kSize);
                      std::vector<std::uint32_t> seedCellOf(kSize);
                      for (std::size_t g = r.begin(); g != r.end(); ++g) {
                        tracker.advance();
                        const Coord origin = plan.pairs[plan.groupStart[g]].first;
                        seedLeaf(plan, g, best, seeds, seedCellOf);
                        auto& out = leafResults[g];
                        for (int n = 0; n < kSize; ++n) {
                          if (!(best[n] < std::numeric_limits<double>::infinity())) continue;
                          // The preimage is within the cell's slack of the seed; it must be in an
                          // active voxel.
                          const Cell& seedCell = plan.cells[seedCellOf[n]];
                          if (!nearActive(acc, seeds[n], seedCell.slack)) continue;
                          const Coord ijk =
                              origin + LeafT::offsetToLocalCoord(static_cast<openvdb::Index>(n));
                          const Vec3 y = plan.frame.toWorld(Vec3(ijk.x(), ijk.y(), ijk.z()));
                          InverseHint hint;
                          hint.seed = plan.frame.toWorld(seeds[n]);
                          hint.chordInverse = seedCell.worldJacobianInverse;
                          const InverseResult s = inverse(*plan.warp, y, firstSolve, hint);
                          ++out.solved;
                          out.iterations += static_cast<std::size_t>(s.iterations);
                          out.maxIterations = std::max(out.maxIterations, s.iterations);
                          if (!s.converged) {
                            out.retries.push_back({n, seedCellOf[n]});
                            continue;
                          }
                          sampler.settle(acc, out, origin, n, s.x, seedCellOf[n]);
                        }
                      }
                    });
}

// Stage 5. Second chance for the voxels where the first solve failed (few, and only where the
// warp is not smooth or not invertible): continuation from the center of the seeding cell, whose
// image is known. Each depends only on its own voxel, so the result is thread-independent.
template <typename GridT>
void retryFailures(const GridPlan<GridT>& plan, const VoxelSampler<GridT>& sampler,
                   const InverseOptions& inverseOptions,
                   std::vector<LeafResult<typename GridPlan<GridT>::LeafT>>& leafResults) {
  using LeafT = typename GridPlan<GridT>::LeafT;
  const IndexFrame& frame = plan.frame;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, plan.groups(), 16),
      [&](const tbb::blocked_range<std::size_t>& r) {
        typename VoxelSampler<GridT>::Accessor acc(plan.tree());
        for (std::size_t g = r.begin(); g != r.end(); ++g) {
          auto& out = leafResults[g];
          if (out.retries.empty()) continue;
          if (!inverseOptions.continuation) {
            out.failures += out.retries.size();
            out.retries = {};
            continue;
          }
          const Coord origin = plan.pairs[plan.groupStart[g]].first;
          for (const Retry& retry : out.retries) {
            const Cell& cell = plan.cells[retry.cell];
            const Coord ijk =
                origin + LeafT::offsetToLocalCoord(static_cast<openvdb::Index>(retry.n));
            const Vec3 y = frame.toWorld(Vec3(ijk.x(), ijk.y(), ijk.z()));
            // The preimage must keep the orientation of the cell's affine model along the
            // whole path: where the warp turns space inside out, it folds.
            const double orientation =
                glm::determinant(cell.worldJacobianInverse) > 0.0 ? 1.0 : -1.0;
            const InverseResult s = continueInverse(
                *plan.warp, y, {frame.toWorld(cell.center), frame.toWorld(cell.image), orientation},
                inverseOptions);
            out.iterations += static_cast<std::size_t>(s.iterations);
            out.maxIterations = std::max(out.maxIterations, s.iterations);
            if (!s.converged) {
              ++out.failures;
              continue;
            }
            sampler.settle(acc, out, origin, retry.n, s.x, retry.cell);
          }
          out.retries = {};
        }
      });
}

// The output grid from the solved leaves, with the input's transform, name, class and metadata;
// the leaves' counts go into the report. Returns the grid and Σ value over its voxels.
template <typename GridT>
std::pair<typename GridT::Ptr, double> assembleGrid(
    const GridPlan<GridT>& plan,
    std::vector<LeafResult<typename GridPlan<GridT>::LeafT>>& leafResults,
    WarpVolumeReport& report) {
  const GridT& in = plan.in;
  auto tree = std::make_shared<typename GridPlan<GridT>::TreeT>(in.background());
  double massAfter = 0.0;
  for (auto& lr : leafResults) {
    report.solvedVoxels += lr.solved;
    report.inverseFailures += lr.failures;
    report.vectorFailures += lr.vectorFailures;
    report.totalNewtonIterations += lr.iterations;
    report.maxNewtonIterations = std::max(report.maxNewtonIterations, lr.maxIterations);
    massAfter += lr.mass;
    detail::joinVolumeChange(report, lr.minVolumeChange, lr.maxVolumeChange);
    report.degenerateVolumeChanges += lr.degenerateVolumeChanges;
    if (lr.leaf) tree->addLeaf(lr.leaf.release());
  }
  typename GridT::Ptr grid = GridT::create(tree);
  grid->setTransform(in.transform().copy());
  for (auto it = in.beginMeta(); it != in.endMeta(); ++it) {
    if (it->first.rfind("file_", 0) == 0) continue;  // stale statistics of the input file
    // Name and class are set below as strings; a file may store them under another type (a
    // type OpenVDB does not know), which insertMeta would keep and the setters then refuse.
    if (it->first == openvdb::GridBase::META_GRID_NAME ||
        it->first == openvdb::GridBase::META_GRID_CLASS)
      continue;
    grid->insertMeta(it->first, *it->second);
  }
  grid->setName(in.getName());
  grid->setGridClass(in.getGridClass());
  return {grid, massAfter};
}

// min(1, the smallest singular value of J over the valid cells): how much the warp compresses.
double smallestStretch(const std::vector<Cell>& cells) {
  double sigmaMin = 1.0;
  for (const Cell& cell : cells)
    if (cell.valid) sigmaMin = std::min(sigmaMin, 1.0 / spectralNorm(cell.jacobianInverse));
  return sigmaMin;
}

// Level sets: a proper narrow band again (see LevelSetRedistance), unless the warp is rigid.
template <typename GridT>
void redistanceLevelSet(typename GridT::ValueType inputBackground, bool rigid, double sigmaMin,
                        const WarpVolumeOptions& options, typename GridT::Ptr& grid,
                        WarpVolumeReport& report) {
  openvdb::tools::signedFloodFill(grid->tree());
  if (options.redistance == LevelSetRedistance::Rebuild && !rigid) {
    const float w = static_cast<float>(report.halfWidth);
    typename GridT::Ptr rebuilt = openvdb::tools::levelSetRebuild(*grid, 0.0f, w, w);
    rebuilt->setTransform(grid->transform().copy());
    for (auto it = grid->beginMeta(); it != grid->endMeta(); ++it)
      rebuilt->insertMeta(it->first, *it->second);
    grid = rebuilt;
    report.redistanced = true;
  } else if (options.redistance == LevelSetRedistance::Normalize && !rigid) {
    // Where the warp compresses by σ, the resampled band is σ times as wide: grow it.
    const double w = report.halfWidth;
    const int layers = static_cast<int>(
        std::clamp(std::ceil(w / std::max(sigmaMin, 1e-3) - w - 1e-6), 0.0, 2.0 * std::ceil(w)));
    openvdb::tools::LevelSetTracker<GridT> redistance(*grid);
    redistance.setNormCount(options.normCount);
    redistance.setSpatialScheme(openvdb::math::FIRST_BIAS);
    redistance.setTemporalScheme(openvdb::math::TVD_RK1);
    if (layers > 0) redistance.dilate(layers);
    redistance.normalize();
    if (layers > 0) openvdb::tools::changeLevelSetBackground(grid->tree(), inputBackground);
    redistance.prune();
    report.redistanced = true;
    report.bandLayersAdded = layers;
  }
}

// warpVolume() for one grid type: plan (cells, leaves), solve, second chance, assemble, and
// re-distance level sets.
// With a part, only its leaves are solved and level sets are not re-distanced.
template <typename GridT>
WarpedGrid<GridT> resampleGrid(const Warp& exactWarp, const GridT& in,
                               const WarpVolumeOptions& options,
                               detail::VolumePart* part = nullptr) {
  validate(options);
  WarpedGrid<GridT> result;
  WarpVolumeReport& report = result.report;
  const GridPlan<GridT> plan = makePlan(exactWarp, in, options, report, part);

  // The solver's tolerance and continuation steps are in voxels.
  InverseOptions inverseOptions = options.inverse;
  inverseOptions.lengthScale = plan.frame.voxelSize;
  InverseOptions firstSolve = inverseOptions;
  firstSolve.continuation = false;  // the second chance runs apart, after every first solve
  // The seeded solve takes 1–3 steps on smooth warps; closed forms are not used, so volumes
  // do not depend on which warps have one.
  firstSolve.closedForm = false;

  std::vector<LeafResult<typename GridPlan<GridT>::LeafT>> leafResults(plan.groups());
  ProgressTracker tracker(options.progress, "warp volume", plan.groups());
  const VoxelSampler<GridT> sampler(plan);
  if constexpr (!GridPlan<GridT>::kScalar) report.vectors = describe(sampler.vectors());
  solveLeaves(plan, sampler, firstSolve, leafResults, tracker);
  tracker.check();
  retryFailures(plan, sampler, inverseOptions, leafResults);

  if (part)
    for (const auto& lr : leafResults) part->haloMisses += lr.haloMisses;
  auto [grid, massAfter] = assembleGrid(plan, leafResults, report);
  if constexpr (GridPlan<GridT>::kScalar) {
    if (plan.levelSet) {
      if (!part)
        redistanceLevelSet<GridT>(in.background(), plan.rigid, smallestStretch(plan.cells), options,
                                  grid, report);
    } else {
      report.massAfter = massAfter * plan.voxelVolume;
    }
  }
  tracker.finish();
  report.outputActiveVoxels = static_cast<std::size_t>(grid->activeVoxelCount());
  result.grid = grid;
  return result;
}

}  // namespace

WarpedGrid<openvdb::FloatGrid> warpVolume(const Warp& warp, const openvdb::FloatGrid& grid,
                                          const WarpVolumeOptions& options) {
  return resampleGrid(warp, grid, options);
}

WarpedGrid<openvdb::DoubleGrid> warpVolume(const Warp& warp, const openvdb::DoubleGrid& grid,
                                           const WarpVolumeOptions& options) {
  return resampleGrid(warp, grid, options);
}

WarpedGrid<openvdb::Vec3SGrid> warpVolume(const Warp& warp, const openvdb::Vec3SGrid& grid,
                                          const WarpVolumeOptions& options) {
  return resampleGrid(warp, grid, options);
}

namespace detail {

namespace {

template <typename GridT>
VolumeCellImages cellImagesOf(const Warp& warp, const GridT& in, const WarpVolumeOptions& options,
                              WarpVolumeReport& report) {
  validate(options);
  const GridPlan<GridT> plan = makePlan(warp, in, options, report);
  VolumeCellImages images;
  images.rigid = plan.rigid;
  images.smallestStretch = smallestStretch(plan.cells);
  const int c = options.seedSpacing;
  // Split cells keep their parent's key; cells are grouped per key in key order.
  std::vector<std::pair<Coord, CoordBBox>> boxes;
  boxes.reserve(plan.cells.size());
  for (const Cell& cell : plan.cells) {
    const Coord key(floorDiv(cell.lo.x(), c), floorDiv(cell.lo.y(), c), floorDiv(cell.lo.z(), c));
    boxes.emplace_back(key, cell.valid ? cell.outBox : CoordBBox());
  }
  std::stable_sort(boxes.begin(), boxes.end(),
                   [](const auto& a, const auto& b) { return coordLess(a.first, b.first); });
  for (const auto& [key, box] : boxes) {
    if (images.keys.empty() || images.keys.back() != key) {
      images.keys.push_back(key);
      images.outBoxes.emplace_back();
    }
    if (!box.empty()) images.outBoxes.back().expand(box);
  }
  return images;
}

template <typename GridT>
WarpedGrid<openvdb::GridBase> partOf(const Warp& warp, const GridT& in,
                                     const WarpVolumeOptions& options, VolumePart& part) {
  WarpedGrid<GridT> r = resampleGrid(warp, in, options, &part);
  return {r.grid, r.report};
}

}  // namespace

VolumeCellImages volumeCellImages(const Warp& warp, const openvdb::GridBase& grid,
                                  const WarpVolumeOptions& options, WarpVolumeReport& report) {
  if (const auto* g = dynamic_cast<const openvdb::FloatGrid*>(&grid))
    return cellImagesOf(warp, *g, options, report);
  if (const auto* g = dynamic_cast<const openvdb::DoubleGrid*>(&grid))
    return cellImagesOf(warp, *g, options, report);
  if (const auto* g = dynamic_cast<const openvdb::Vec3SGrid*>(&grid))
    return cellImagesOf(warp, *g, options, report);
  throw InvalidInput("warpVolume: grid '" + grid.getName() + "' of type " + grid.type() +
                     " cannot be warped in parts (float, double and vec3s grids can)");
}

WarpedGrid<openvdb::GridBase> warpVolumePart(const Warp& warp, const openvdb::GridBase& grid,
                                             const WarpVolumeOptions& options, VolumePart& part) {
  if (options.cacheSpacing > 0.0) {
    throw InvalidInput("warpVolume: grid '" + grid.getName() +
                       "': cacheSpacing cannot be used when warping in parts (its lattice "
                       "depends on every cell of the grid)");
  }
  if (const auto* g = dynamic_cast<const openvdb::FloatGrid*>(&grid))
    return partOf(warp, *g, options, part);
  if (const auto* g = dynamic_cast<const openvdb::DoubleGrid*>(&grid))
    return partOf(warp, *g, options, part);
  if (const auto* g = dynamic_cast<const openvdb::Vec3SGrid*>(&grid))
    return partOf(warp, *g, options, part);
  throw InvalidInput("warpVolume: grid '" + grid.getName() + "' of type " + grid.type() +
                     " cannot be warped in parts (float, double and vec3s grids can)");
}

void redistanceVolume(openvdb::GridBase::Ptr& grid, double inputBackground, bool rigid,
                      double smallestStretch, const WarpVolumeOptions& options,
                      WarpVolumeReport& report) {
  if (auto g = openvdb::GridBase::grid<openvdb::FloatGrid>(grid)) {
    redistanceLevelSet<openvdb::FloatGrid>(static_cast<float>(inputBackground), rigid,
                                           smallestStretch, options, g, report);
    grid = g;
  } else if (auto d = openvdb::GridBase::grid<openvdb::DoubleGrid>(grid)) {
    redistanceLevelSet<openvdb::DoubleGrid>(inputBackground, rigid, smallestStretch, options, d,
                                            report);
    grid = d;
  }
}

void joinVolumeChange(WarpVolumeReport& report, double minChange, double maxChange) {
  if (!(maxChange > 0.0)) return;
  report.minVolumeChange =
      report.maxVolumeChange == 0.0 ? minChange : std::min(report.minVolumeChange, minChange);
  report.maxVolumeChange = std::max(report.maxVolumeChange, maxChange);
}

}  // namespace detail

}  // namespace spacewarp
