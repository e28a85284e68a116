// ImplicitField: the fitted multi-level CSRBF function f (docs/method.md §5–§6) as a value type, with
// batched evaluation of f, ∇f and the Hessian on any device, and a versioned binary file format.
#pragma once

#include <array>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "duplexfit/device.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

/// One level k of the field: support σ_k, centres c_j and weights w_j, in normalised coordinates.
struct FieldLevel {
  double sigma = 0.0;
  Points centres;           ///< #C×3
  Eigen::VectorXd weights;  ///< #C
};

/// The similarity transform between input ("world") coordinates and the normalised unit box the fit
/// works in: u = scale·(x − centre). Field values scale likewise: f_world = f_normalised / scale.
struct Normalization {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double scale = 1.0;
};

/// Results of a batched evaluation, in world units, one row per query.
struct FieldSamples {
  Eigen::VectorXd values;  ///< f
  Points gradients;        ///< ∇f (#Q×3; empty unless requested)
  /// Hessians as #Q×6 (xx, xy, xz, yy, yz, zz; empty unless requested)
  Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor> hessians;
};

/// What to compute in a batched evaluation.
enum class FieldDerivatives { None, Gradient, Hessian };

/// f(x) = f0 + Σ_k Σ_j w_kj φ(‖u − c_kj‖/σ_k)/scale with u the normalised x; positive inside the solid,
/// ≈ signed distance (world units) near the surface, → f0/scale far away. Offsets are the δ values of
/// the level sets fitted with it ({f = δ}; δ > 0 inward).
class ImplicitField {
 public:
  ImplicitField() = default;
  ImplicitField(Normalization normalization, double f0, std::vector<FieldLevel> levels,
                std::vector<double> offsets, Eigen::AlignedBox3d worldBounds);

  const Normalization& normalization() const noexcept { return normalization_; }
  double f0() const noexcept { return f0_; }
  const std::vector<FieldLevel>& levels() const noexcept { return levels_; }
  const std::vector<double>& offsets() const noexcept { return offsets_; }
  /// The bounding box of the input points (world units).
  const Eigen::AlignedBox3d& bounds() const noexcept { return bounds_; }
  std::size_t centreCount() const noexcept;

  /// f at one point (reference path, world coordinates and units).
  double value(const Eigen::Vector3d& x) const;
  /// ∇f at one point (reference path).
  Eigen::Vector3d gradient(const Eigen::Vector3d& x) const;
  /// Hessian at one point (reference path).
  Eigen::Matrix3d hessian(const Eigen::Vector3d& x) const;

  /// Batched evaluation at #Q×3 world points on a device (OpenCL kernel or reference loops), in the
  /// given precision. For repeated calls build a FieldEvaluator once instead.
  FieldSamples evaluate(const Device& device, const Points& queries,
                        FieldDerivatives derivatives = FieldDerivatives::None,
                        Precision precision = Precision::Float) const;

  /// Writes the versioned binary field file (format in docs/field-format.md).
  void save(std::ostream& out) const;
  /// Writes to a path atomically (temporary file, then rename). @throws IoError.
  void save(const std::string& path) const;
  /// @throws IoError on a bad magic, unknown version, truncation or checksum mismatch (naming `source`).
  static ImplicitField load(std::istream& in, const std::string& source = "<stream>");
  static ImplicitField load(const std::string& path);

 private:
  Normalization normalization_;
  double f0_ = -1.0;
  std::vector<FieldLevel> levels_;
  std::vector<double> offsets_;
  Eigen::AlignedBox3d bounds_;
};

namespace detail {
struct EvaluatorImpl;
}

/// A field (or its first `levelCount` levels) uploaded once to a device with per-level uniform grids,
/// for many batched evaluations (polygonization, slicing, the fit's right-hand sides). A fit builds one
/// and appends each level as it is solved, then hands it on to extraction (FitResult::evaluator).
class FieldEvaluator {
 public:
  /// @param levelCount how many levels to use (from the coarsest); −1: all
  /// @throws DeviceError (precision unavailable, buffers above the device's max allocation)
  FieldEvaluator(const Device& device, const ImplicitField& field, Precision precision = Precision::Float,
                 int levelCount = -1);
  /// An evaluator of the constant field f0 (normalised units) with no levels yet: see appendLevel.
  /// @throws DeviceError (precision unavailable)
  FieldEvaluator(const Device& device, const Normalization& normalization, double f0,
                 Precision precision = Precision::Float);
  /// Adds a finer level (normalised coordinates, like ImplicitField's levels): only its centres and
  /// grid are uploaded; evaluation then sums it too. Results are identical to an evaluator built from
  /// the whole field at once. @throws DeviceError (buffers above the device's max allocation)
  void appendLevel(const FieldLevel& level);
  /// Removes the finest level: evaluation then sums the levels before it, with results identical to an
  /// evaluator built from those alone, and appendLevel can add another in its place (the fit's overshoot
  /// check solves its finest level again). Nothing already on the device is uploaded again.
  /// @throws InvalidArgument when there is no level
  void dropLastLevel();
  /// Levels summed so far.
  int levelCount() const noexcept;
  FieldEvaluator(FieldEvaluator&&) noexcept;
  FieldEvaluator& operator=(FieldEvaluator&&) noexcept;
  ~FieldEvaluator();

  /// Evaluates at world points. Queries are processed in chunks, so any number fits.
  FieldSamples evaluate(const Points& queries, FieldDerivatives derivatives = FieldDerivatives::None) const;
  /// Evaluates at points given in normalised coordinates, returning normalised values (internal use by
  /// the fit: f_{k−1} at level-k centres).
  Eigen::VectorXd evaluateNormalized(const Points& normalizedQueries) const;
  const Device& device() const;

 private:
  std::unique_ptr<detail::EvaluatorImpl> impl_;
};

}  // namespace duplexfit
