#pragma once
// What the volume bindings share (volume.cpp, volume_bricks.cpp): options from the keyword
// arguments, report dicts and loss warnings.

#include <string>

#include "common.h"

#ifdef SPACEWARP_WITH_OPENVDB
#include <spacewarp/volume/warp_volume.h>
#endif

namespace spacewarp::python {

#ifdef SPACEWARP_WITH_OPENVDB
/// The options of warpVolume() from the keyword arguments (their names are the CLI's flags).
/// Throws InvalidInput naming the option for an unknown choice.
WarpVolumeOptions volumeOptions(const std::string& sampler, bool conserveMass,
                                const std::string& vectors, const std::string& redistance,
                                int seedSpacing, double cacheSpacing);

/// The report of grid `name` of type `type` as the dict spacewarp.warp_volume returns.
py::dict reportDict(const std::string& name, const std::string& type, const WarpVolumeReport& r);

/// Warns about what a grid lost: voxels whose inverse failed, vectors not transformed.
void warnLosses(const std::string& where, const WarpVolumeReport& r);
#endif

/// spacewarp.warp_volume in bricks (volume_bricks.cpp): the functions spacewarp.dask uses.
void bindVolumeBricks(py::module_& m);

}  // namespace spacewarp::python
