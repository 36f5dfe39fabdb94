#pragma once
// Radial basis kernels φ(r) of the RBF warps, and the options every RBF fit shares.

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/core/progress.h>

namespace spacewarp {
class ArchiveReader;
class ArchiveWriter;
}  // namespace spacewarp

namespace spacewarp {

/// The radial kernel φ(r), r = |c − x| in world units.
enum class RbfKernel {
  Triharmonic,  ///< φ = r³ (Botsch & Kobbelt 2005): C², minimises the triharmonic energy.
  Biharmonic,   ///< φ = r: C⁰ at the centers (a cone), minimises the biharmonic energy.
  ThinPlate,    ///< φ = r² log r (0 at r = 0).
  Gaussian,     ///< φ = exp(−(r/ε)²), ε = RbfOptions::scale.
  InverseMultiquadric,  ///< φ = 1 / sqrt(r² + ε²), ε = RbfOptions::scale.
  WendlandC2,  ///< φ = (1 − r/ρ)⁴₊ (4r/ρ + 1), ρ = RbfOptions::radius: compact support.
};

/// Options of an RBF fit (RbfWarp, RbfCoordinates).
struct RbfOptions {
  /// The kernel. Default: triharmonic r³, the shape-editing kernel of Botsch & Kobbelt (2005),
  /// which needs no scale parameter.
  RbfKernel kernel = RbfKernel::Triharmonic;
  /// ε of the Gaussian and inverse multiquadric kernels, world units, > 0. Default 1: set it to
  /// about the spacing of the centers.
  double scale = 1.0;
  /// ρ, the support radius of the Wendland C2 kernel, world units, > 0. Default 1: it should
  /// cover several neighbouring centers.
  double radius = 1.0;
  /// λ ≥ 0: smoothing (approximation instead of interpolation). The system solved is
  /// [[Φ + σλI, P], [Pᵀ, 0]] with σ = −1 for the biharmonic kernel r (conditionally negative
  /// definite) and σ = +1 for the others, so that any λ > 0 keeps the system definite on the
  /// polynomial-free subspace and larger λ always means a smoother, less interpolating fit.
  /// Default 0: the warp interpolates the targets exactly.
  double smoothing = 0.0;
  /// Two centers closer than this, relative to the bounding-box diagonal of all centers, are
  /// duplicates (merged when their targets agree within the same tolerance, an error
  /// otherwise). Default 1e-10.
  double duplicateTolerance = 1e-10;
  /// Told "fit rbf" and the fraction done (the kernel matrix, its projection, the
  /// factorisation) while the system is set up; may cancel (Cancelled). Default: none. Used by
  /// the constructor it is given to and not kept: options() of the object built has none, and
  /// RbfCoordinates' warps fit without one (a callback bound to the caller's frame would
  /// otherwise be called after that frame is gone).
  ProgressCallback progress;
};

/// "triharmonic", "biharmonic", "thin-plate", "gaussian", "inverse-multiquadric", "wendland".
std::string rbfKernelName(RbfKernel kernel);

/// The kernel of a name rbfKernelName() gives. Throws InvalidInput listing the names otherwise.
RbfKernel rbfKernelFromName(std::string_view name);

/// Every kernel name, in the order of the enum.
std::vector<std::string> rbfKernelNames();

/// φ(r) for r ≥ 0 (world units) with the options' kernel and parameters.
double rbfKernelValue(const RbfOptions& options, double r);

/// φ'(r) / r for r > 0, so that ∇_x φ(|x − c|) = (φ'(r) / r) (x − c). At r = 0 it returns the
/// limit where it is finite (triharmonic 0, Gaussian, inverse multiquadric, Wendland) and 0 for
/// the biharmonic and thin-plate kernels, whose φ'(r)/r diverges while (φ'(r)/r)(x − c) → 0 or
/// (biharmonic, a cone) has no limit: 0 is its symmetric subgradient.
double rbfKernelSlopeOverR(const RbfOptions& options, double r);

/// The range of the kernel scale ε and the Wendland radius ρ, world units: their squares and
/// reciprocal squares, which the kernels compute, stay normal doubles. Beyond it (e.g. a
/// scale of 1e-200, whose 1/ε² is infinite) kernel values would be NaN.
inline constexpr double kMinRbfScale = 1e-150;
inline constexpr double kMaxRbfScale = 1e150;

/// Throws InvalidInput (prefixed with `who`) unless the options are valid: scale and radius
/// finite and within [kMinRbfScale, kMaxRbfScale], smoothing finite and ≥ 0,
/// duplicateTolerance finite and ≥ 0.
void validateRbfOptions(const std::string& who, const RbfOptions& options);

/// Archive (core/archive.h): the options but the progress callback; readRbfOptions() checks
/// them with validateRbfOptions().
void writeRbfOptions(ArchiveWriter& out, const RbfOptions& options);
RbfOptions readRbfOptions(ArchiveReader& in);

/// Why the Gaussian or inverse multiquadric scale ε does not suit `centers` (world units;
/// centers closer than duplicateTolerance × their bounding-box diagonal count as one), as a
/// phrase to put after the scale's value ("is too small for ..."); empty when it suits them,
/// or the kernel has no scale. Refused: an ε outside [kMinRbfScale, kMaxRbfScale]; for the
/// Gaussian an ε so small that exp(−(r/ε)²) underflows to 0 between every two centers (the
/// closest two included: each center is alone, and the warp a set of spikes), and for both an
/// ε so large that the kernel's values across the centers' whole extent are equal in double
/// precision (the fit is singular).
std::string rbfScaleProblem(const RbfOptions& options, std::span<const Vec3> centers);

}  // namespace spacewarp
