// Cross-section pictures of a field (the paper's Fig. 1): f sampled on an axis-aligned plane at pixel
// centres on a device, coloured blue (f < 0, outside) → white (f = 0) → red (f > 0, inside) on a
// symmetric scale, with the 0-level and every offset level drawn as contour lines and, optionally, the
// input points near the plane drawn as dots.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/image.hpp"
#include "duplexfit/types.hpp"
#include "duplexfit/resources.hpp"

namespace duplexfit {

/// An axis-aligned plane {x_axis = value} in world (input) units; axis 0 = x, 1 = y, 2 = z.
///
/// Image axes (right, up) per plane: x = c → (y, z); y = c → (x, z); z = c → (x, y). Image rows go
/// from top to bottom, so the first row is the largest "up" coordinate.
struct SectionPlane {
  int axis = 2;
  double value = 0.0;

  /// Parses "x=0.1", "y=-2", "z=0" (case-insensitive, blanks allowed around '=').
  /// @throws InvalidArgument naming the text.
  static SectionPlane parse(std::string_view text);
  /// "x=0.1" (shortest round-trip form of the value).
  std::string toString() const;
  /// The world axes along the image's right and up directions.
  int rightAxis() const noexcept { return axis == 0 ? 1 : 0; }
  int upAxis() const noexcept { return axis == 2 ? 1 : 2; }
};

/// "x", "y" or "z" (anything else: "?").
const char* sectionAxisName(int axis) noexcept;

/// Options of renderSection. Every length is in world units unless it says pixels.
struct SectionOptions {
  /// Pixels along the image's longer side (16..8192); the other side follows the rectangle's aspect.
  int size = 1024;
  /// The colour scale is ±range; 0: the 99th percentile of |f| over the image (a robust max).
  double range = 0.0;
  /// Colour intensity ∝ (|f|/range)^gamma: 1 is linear; the default 0.5 keeps the small values near the
  /// surface visible when |f| is much larger far outside than inside (f → f0 away from the data).
  double gamma = 0.5;
  /// The part of the plane shown, as (right, up) coordinates; empty (the default): the field's bounds()
  /// projected on the plane, grown by `margin` on every side.
  Eigen::AlignedBox2d rectangle;
  /// Margin around the projected bounds, as a fraction of their longer side (ignored with `rectangle`).
  double margin = 0.05;
  /// Draw the 0-level and offset contour lines.
  bool contours = true;
  /// Contour line width in pixels (anti-aliased; 1–2 px is crisp). 0: 1.5 px up to 1536 px images,
  /// 2 px above.
  double lineWidth = 0.0;
  /// Points (#P×3, world units) to draw as dots when they lie within `band` of the plane.
  Points points;
  /// Half-thickness w of the slab |x_axis − value| < w whose points are drawn; 0: 1% of the longest
  /// side of the field's bounds().
  double band = 0.0;
  /// Dot radius in pixels; 0: 1.5 px, or 1.5·size/1024 for images over 1024 px.
  double dotRadius = 0.0;
  /// Arithmetic of the device evaluation (the Device overload of renderSection; an evaluator passed in
  /// keeps its own).
  Precision precision = Precision::Float;
  /// The memory budget, checked once the image size is known (about 16 bytes a pixel).
  ResourceLimits limits{};
};

/// A rendered section and how its pixels map to the plane.
struct SectionResult {
  Image image;                    ///< RGB, width × height
  SectionPlane plane;
  Eigen::AlignedBox2d rectangle;  ///< (right, up) world coordinates covered by the image (square pixels)
  double pixelSize = 0.0;         ///< world units per pixel
  double range = 0.0;             ///< the colour scale used: ±range
  double minValue = 0.0;          ///< min f over the pixel centres
  double maxValue = 0.0;          ///< max f over the pixel centres
  std::vector<double> levels;     ///< the contour levels drawn: 0, then field.offsets() in order
  std::size_t pointsDrawn = 0;    ///< points within the band whose dot touches the image
  double band = 0.0;              ///< the band actually used (0 without points)
  double seconds = 0.0;           ///< wall time of the evaluation and drawing
  /// f at every pixel centre, row-major from the top row (width × height values).
  std::vector<float> values;

  /// The world point at the centre of pixel (x, y) (x to the right, y down from the top row).
  Eigen::Vector3d pixelCentre(int x, int y) const;
  /// Continuous pixel coordinates (x, y) of a world point projected on the plane; pixel (i, j) covers
  /// [i, i+1) × [j, j+1), so its centre is (i + 0.5, j + 0.5).
  Eigen::Vector2d pixelOf(const Eigen::Vector3d& point) const;
};

/// The colour map: blue for f ≤ −range, white at 0, red for f ≥ range, in between the end colour mixed
/// with white in proportion (|f|/range)^gamma. Non-finite f is grey.
std::array<std::uint8_t, 3> sectionColour(double f, double range, double gamma = 0.5) noexcept;
/// The contour colour of level `index` (0: the 0-level, black; k ≥ 1: offset k, from a palette of
/// dark green, purple, orange, teal, brown, repeating).
std::array<std::uint8_t, 3> sectionContourColour(std::size_t index) noexcept;
/// The colour of the point dots (yellow, with a 1 px dark grey outline).
std::array<std::uint8_t, 3> sectionPointColour() noexcept;

/// Checks the arguments of renderSection without evaluating anything (e.g. before a slow device set-up).
/// @throws InvalidArgument as renderSection.
void validateSection(const ImplicitField& field, const SectionPlane& plane, const SectionOptions& options = {});

/// Renders the section of `field` on `plane` using an evaluator built for it (reuse one evaluator for
/// several planes).
/// @throws InvalidArgument: a plane outside the field's bounds (naming the plane and the box), a size
/// outside 16..8192, a negative or non-finite range, band, margin or line width, a gamma outside (0, 10], a degenerate or
/// non-finite rectangle, a field without bounds; DeviceError from the evaluation.
SectionResult renderSection(const FieldEvaluator& evaluator, const ImplicitField& field, const SectionPlane& plane,
                            const SectionOptions& options = {});

/// renderSection with an evaluator built on `device` for this call (options.precision).
SectionResult renderSection(const Device& device, const ImplicitField& field, const SectionPlane& plane,
                            const SectionOptions& options = {});

}  // namespace duplexfit
