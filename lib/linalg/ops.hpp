// The CG's reduction launcher (internal); the fused steps themselves are public in duplexfit/cg_steps.hpp.
#pragma once

#include <CL/opencl.hpp>

#include <utility>
#include <vector>

#include "duplexfit/cg_steps.hpp"
#include "duplexfit/linalg.hpp"

namespace duplexfit::detail {

// The fused steps are public (duplexfit/cg_steps.hpp); the library names them here as before.
using steps::CgSums;
using steps::cgDirection;
using steps::cgUpdate;
using steps::cgUpdateXR;
using steps::resolveSpmvKernel;
using steps::spmvDot;
using steps::triad;
using steps::vmul;

/// Launches a reduction kernel whose arguments before `partialArg` are set, over n elements with
/// `perItem` partial values per chunk/group, and returns the partials combined per slot (perItem values):
/// summed, except slot `maxSlot` (if < perItem), which takes the maximum.
std::vector<double> reduceLaunch(const Device& device, Precision precision, cl::Kernel& kernel,
                                 unsigned partialArg, std::size_t n, std::size_t perItem, const char* name,
                                 std::size_t maxSlot = static_cast<std::size_t>(-1));
}  // namespace duplexfit::detail
