// Launchers of the "preprocess" kernels: one call per pass, on an OpenCL device or, on the reference
// device, through the C++ twins in preprocess_ref.hpp. Inputs are double arrays (centred positions);
// they are converted to the requested precision here.
#pragma once

#include <cstdint>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::detail {

/// One bilateral pass: displacements (3 per point) for positions pos and normals nrm (3 per point), area
/// weights, CSR neighbour lists (offsets n + 1, indices into the points), a = 1/(2σ_ψ²), b = range factor.
std::vector<double> bilateralPass(const Device& device, Precision precision, const std::vector<double>& pos,
                                  const std::vector<double>& nrm, const std::vector<double>& area,
                                  const std::vector<std::uint32_t>& offsets, const std::vector<std::uint32_t>& nbr,
                                  double a, double b);

/// Neighbourhood covariances (6 per point: xx xy xz yy yz zz) of fixed-size neighbourhoods of k1 points
/// (nbr holds n·k1 indices).
std::vector<double> pcaCovariances(const Device& device, Precision precision, const std::vector<double>& pos,
                                   std::size_t k1, const std::vector<std::uint32_t>& nbr);

}  // namespace duplexfit::detail
