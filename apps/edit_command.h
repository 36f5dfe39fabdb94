#pragma once
// `spacewarp edit`: surface editing of a mesh file by handle regions (surface/), shared with
// the demo.

#include <cstddef>
#include <string>

#include <spacewarp/rig/cage_rig.h>
#include <spacewarp/surface/cage_arap.h>
#include <spacewarp/surface/edit_mesh.h>
#include <spacewarp/surface/surface_mesh.h>
#include "apps/cli_context.h"

namespace spacewarp::cli {

/// One edit, as the command line gives it (see `spacewarp edit --help` and README.md).
struct EditRequest {
  std::string method;               ///< laplacian, bilaplacian, arap or cage-arap
  std::string handles;              ///< the handles file (JSON)
  std::string model;                ///< the mesh to edit (.obj, .off, .ply)
  std::string output;               ///< the edited mesh (.obj, .off, .ply)
  std::string cage;                 ///< cage-arap: the cage file
  std::string cageOut;              ///< cage-arap: where to write the posed cage ("" for nowhere)
  std::string lattice;              ///< cage-arap: an ffd rig file whose lattice replaces the cage
  std::string latticeOut;           ///< cage-arap with a lattice: where to write the posed ffd rig
  std::string coordinates = "mvc";  ///< cage-arap: the cage coordinates (cageMethods())
  bool ascii = false;               ///< PLY output as ASCII
  double weldTolerance = WeldOptions{}.relativeTolerance;
  std::string energy = "spokes-and-rims";  ///< arap, cage-arap: spokes-and-rims or spokes
  int iterations = 0;                      ///< arap, cage-arap: 0 keeps the method's default
  int acceleration = -1;                   ///< arap, cage-arap: < 0 keeps the default window
  double tolerance = -1.0;                 ///< arap, cage-arap: < 0 keeps the method's default
  std::size_t clusters = 0;                ///< cage-arap: CageArapOptions::rotationClusters
  double handleWeight = CageArapOptions{}.handleWeight;
  double reachTolerance = CageArapOptions{}.reachTolerance;
  CageMethodOptions cageOptions;  ///< cage-arap with harmonic coordinates
};

/// Reads the model and the handles, edits, writes the output (and the posed cage) atomically,
/// reporting through `context`. Throws the library's typed errors naming the file at fault.
void runEdit(const EditRequest& request, const CliContext& context);

}  // namespace spacewarp::cli
