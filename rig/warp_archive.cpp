#include <spacewarp/rig/warp_archive.h>

#include <spacewarp/coords/discrete_harmonic.h>
#include <spacewarp/coords/green.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/quad_green.h>
#include <spacewarp/coords/quad_mean_value.h>
#include <spacewarp/coords/wachspress.h>
#include <spacewarp/core/bend.h>
#include <spacewarp/core/combinators.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/taper.h>
#include <spacewarp/core/twist.h>
#include <spacewarp/ffd/lattice_coordinates.h>
#include <spacewarp/ffd/lattice_warp.h>
#include <spacewarp/rbf/rbf_coordinates.h>
#include <spacewarp/rbf/rbf_warp.h>
#include <spacewarp/rig/detail/rbf_rig.h>
#ifdef SPACEWARP_HAVE_HARMONIC
#include <spacewarp/coords/harmonic.h>
#include <spacewarp/coords/harmonic_warp.h>
#endif
#include <spacewarp/nonlinear/deformation_graph.h>
#include <spacewarp/nonlinear/kelvinlet.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/nonlinear/shepard.h>
#include <spacewarp/nonlinear/skinning.h>
#include <spacewarp/nonlinear/wires.h>
#ifdef SPACEWARP_WITH_OPENVDB
#include <spacewarp/volume/inside_distance.h>
#endif

namespace spacewarp {

namespace {

// A loader that returns its class's load() as the interface's pointer.
template <class Base, class T>
std::function<std::shared_ptr<const Base>(ArchiveReader&)> loader() {
  return [](ArchiveReader& in) -> std::shared_ptr<const Base> { return T::load(in); };
}

ArchiveLoaders makeLoaders() {
  ArchiveLoaders l;
  // Warps, one line per tag.
  l.warps.emplace("identity", loader<Warp, IdentityWarp>());
  l.warps.emplace("affine", loader<Warp, AffineWarp>());
  l.warps.emplace("compose", loader<Warp, ComposedWarp>());
  l.warps.emplace("twist", loader<Warp, TwistWarp>());
  l.warps.emplace("bend", loader<Warp, BendWarp>());
  l.warps.emplace("taper", loader<Warp, TaperWarp>());
  l.warps.emplace("coordinate-warp", loader<Warp, CoordinateWarp>());
  l.warps.emplace("lattice-warp", loader<Warp, LatticeWarp>());
  l.warps.emplace("rbf-warp", loader<Warp, RbfWarp>());
#ifdef SPACEWARP_HAVE_HARMONIC
  l.warps.emplace("harmonic-warp", loader<Warp, HarmonicWarp>());
#endif
  // Coordinates, one line per tag.
  l.coordinates.emplace("mean-value", loader<Coordinates, MeanValueCoordinates>());
  l.coordinates.emplace("green", loader<Coordinates, GreenCoordinates>());
  l.coordinates.emplace("quad-mean-value", loader<Coordinates, QuadMeanValueCoordinates>());
  l.coordinates.emplace("quad-green", loader<Coordinates, QuadGreenCoordinates>());
  l.coordinates.emplace("wachspress", loader<Coordinates, WachspressCoordinates>());
  l.coordinates.emplace("discrete-harmonic", loader<Coordinates, DiscreteHarmonicCoordinates>());
#ifdef SPACEWARP_HAVE_HARMONIC
  l.coordinates.emplace("harmonic", loader<Coordinates, HarmonicCoordinates>());
#endif
  l.coordinates.emplace("lattice", loader<Coordinates, LatticeCoordinates>());
  l.coordinates.emplace("rbf-coordinates", loader<Coordinates, RbfCoordinates>());
  l.coordinates.emplace("lazy-rbf-coordinates", &detail::loadLazyRbfCoordinates);
  // HandleDistances, one line per tag.

  // nonlinear/ and volume/, one line per tag.
  l.warps.emplace("mls", loader<Warp, MlsWarp>());
  l.warps.emplace("deformation-graph", loader<Warp, DeformationGraphWarp>());
  l.warps.emplace("wires", loader<Warp, WiresWarp>());
  l.warps.emplace("kelvinlet", loader<Warp, KelvinletWarp>());
  l.warps.emplace("skinning", loader<Warp, SkinningWarp>());
  l.warps.emplace("shepard-warp", loader<Warp, ShepardWarp>());
  l.coordinates.emplace("mls-affine", loader<Coordinates, MlsAffineCoordinates>());
  l.coordinates.emplace("shepard", loader<Coordinates, ShepardCoordinates>());
#ifdef SPACEWARP_WITH_OPENVDB
  l.distances.emplace("inside-distances", loader<HandleDistances, InsideDistances>());
#endif
  return l;
}

ArchiveWriter withHeader() {
  ArchiveWriter out;
  out.string(kArchiveMagic);
  out.u32(kArchiveVersion);
  return out;
}

void readHeader(ArchiveReader& in, std::string_view bytes) {
  // The magic is written as a string: its length, then the text. Compare the raw prefix first,
  // so that any other file is named as "not an archive" rather than by a truncation.
  const std::string expected = withHeader().bytes().substr(0, 8 + kArchiveMagic.size());
  if (bytes.substr(0, expected.size()) != expected)
    in.fail("not a spacewarp archive: it does not start with \"" + std::string(kArchiveMagic) +
            "\"");
  in.string();
  const std::uint32_t version = in.u32();
  if (version != kArchiveVersion)
    in.fail("format version " + std::to_string(version) + ", but this build reads version " +
            std::to_string(kArchiveVersion));
}

// What `read` reads after the header, which must be the whole rest of `bytes`.
template <class Read>
auto readWhole(std::string_view bytes, Read&& read) {
  ArchiveReader in(bytes, archiveLoaders());
  readHeader(in, bytes);
  auto object = read(in);
  if (!in.atEnd())
    in.fail(std::to_string(bytes.size() - in.position()) + " bytes after the end of the object");
  return object;
}

}  // namespace

const ArchiveLoaders& archiveLoaders() {
  static const ArchiveLoaders loaders = makeLoaders();
  return loaders;
}

std::string saveWarp(const Warp& warp) {
  ArchiveWriter out = withHeader();
  out.warp(warp);
  return out.bytes();
}

std::shared_ptr<const Warp> loadWarp(std::string_view bytes) {
  return readWhole(bytes, [](ArchiveReader& in) { return in.warp(); });
}

std::string saveCoordinates(const Coordinates& coordinates) {
  ArchiveWriter out = withHeader();
  out.coordinates(coordinates);
  return out.bytes();
}

std::shared_ptr<const Coordinates> loadCoordinates(std::string_view bytes) {
  return readWhole(bytes, [](ArchiveReader& in) { return in.coordinates(); });
}

std::string saveDistances(const HandleDistances& distances) {
  ArchiveWriter out = withHeader();
  out.distances(distances);
  return out.bytes();
}

std::shared_ptr<const HandleDistances> loadDistances(std::string_view bytes) {
  return readWhole(bytes, [](ArchiveReader& in) { return in.distances(); });
}

std::string saveCage(const Cage& cage) {
  ArchiveWriter out = withHeader();
  cage.save(out);
  return out.bytes();
}

Cage loadCage(std::string_view bytes) {
  return readWhole(bytes, [](ArchiveReader& in) {
    const std::size_t start = in.position();
    try {
      return Cage::load(in);
    } catch (const InvalidInput& e) {
      throw InvalidInput(ArchiveReader::inContext("cage", start, e.what()));
    }
  });
}

}  // namespace spacewarp
