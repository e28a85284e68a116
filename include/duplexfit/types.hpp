// Basic value types shared by the whole public API: points as row-major n×3 double matrices, and the
// arithmetic precision of device computations.
#pragma once

#include <cstdint>

#include <Eigen/Core>

namespace duplexfit {

/// Points (or normals) as an #P×3 row-major matrix, one point per row, in model units.
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Index type of sparse matrices and neighbour lists (limits a matrix to 2^31 − 1 non-zeros).
using Index = std::int32_t;

/// Arithmetic precision of device-side computations. Float always works; Double needs a device that
/// reports cl_khr_fp64 (the reference device always has it).
enum class Precision { Float, Double };

/// "float" or "double".
const char* precisionName(Precision precision) noexcept;

/// Parses "float"/"single"/"f32" or "double"/"f64" (case-insensitive).
/// @throws InvalidArgument naming the text for anything else.
Precision parsePrecision(const char* text);

}  // namespace duplexfit
