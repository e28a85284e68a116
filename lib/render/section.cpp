// Cross-section pictures of a field: pixel-centre samples of f on an axis-aligned plane (batched on the
// device through FieldEvaluator), a diverging blue–white–red colour map on a symmetric scale, anti-aliased
// contour lines of the 0-level and the offset levels placed by the sampled values, and dots for the input
// points near the plane.
#include "duplexfit/section.hpp"
#include "duplexfit/timer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "duplexfit/error.hpp"

namespace duplexfit {

namespace {

using Rgb = std::array<std::uint8_t, 3>;

constexpr int kMinSize = 16;
constexpr int kMaxSize = 8192;  // 64M pixels: 16384 took 2 GB and over 120 s
/// Pixel centres per evaluation batch (the evaluator's own chunk size).
constexpr std::size_t kBatchPoints = std::size_t{1} << 20;
/// At most this many |f| samples feed the robust range (a strided subset of the image).
constexpr std::size_t kRangeSamples = std::size_t{1} << 20;

std::string shortest(double v) {
  char buf[40];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof buf, "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

/// Six significant digits, for messages.
std::string brief(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string boxText(const Eigen::AlignedBox3d& b) {
  return "(" + brief(b.min().x()) + ", " + brief(b.min().y()) + ", " + brief(b.min().z()) + ")–(" +
         brief(b.max().x()) + ", " + brief(b.max().y()) + ", " + brief(b.max().z()) + ")";
}

void requireNonNegative(double v, const char* name) {
  if (!std::isfinite(v) || v < 0.0) {
    throw InvalidArgument(std::string("section: ") + name + " " + shortest(v) + " (must be finite and >= 0)");
  }
}

void validateImpl(const ImplicitField& field, const SectionPlane& plane, const SectionOptions& o) {
  if (plane.axis < 0 || plane.axis > 2) {
    throw InvalidArgument("section: plane axis " + std::to_string(plane.axis) + " (must be 0, 1 or 2: x, y or z)");
  }
  if (!std::isfinite(plane.value)) throw InvalidArgument("section: plane " + plane.toString() + " is not finite");
  if (o.size < kMinSize || o.size > kMaxSize) {
    throw InvalidArgument("section: size " + std::to_string(o.size) + " px (must be " + std::to_string(kMinSize) +
                          ".." + std::to_string(kMaxSize) + ")");
  }
  requireNonNegative(o.range, "range");
  requireNonNegative(o.margin, "margin");
  requireNonNegative(o.lineWidth, "line width");
  requireNonNegative(o.band, "band");
  requireNonNegative(o.dotRadius, "dot radius");
  if (!(o.gamma > 0.0 && o.gamma <= 10.0)) {
    throw InvalidArgument("section: gamma " + shortest(o.gamma) + " (must be in (0, 10])");
  }
  const Eigen::AlignedBox3d& box = field.bounds();
  if (box.isEmpty() || !box.min().allFinite() || !box.max().allFinite()) {
    throw InvalidArgument("section: the field has no bounding box (empty field)");
  }
  const double lo = box.min()[plane.axis], hi = box.max()[plane.axis];
  const double slack = 1e-9 * std::max(1.0, box.sizes().maxCoeff());
  if (plane.value < lo - slack || plane.value > hi + slack) {
    throw InvalidArgument("section: plane " + plane.toString() + " lies outside the field's box: " +
                          sectionAxisName(plane.axis) + " must be in [" + brief(lo) + ", " + brief(hi) + "] (box " +
                          boxText(box) + ")");
  }
  if (!o.rectangle.isEmpty()) {
    const Eigen::Vector2d s = o.rectangle.sizes();
    if (!o.rectangle.min().allFinite() || !o.rectangle.max().allFinite() || !(s.x() > 0.0) || !(s.y() > 0.0)) {
      throw InvalidArgument("section: rectangle (" + shortest(o.rectangle.min().x()) + ", " +
                            shortest(o.rectangle.min().y()) + ")–(" + shortest(o.rectangle.max().x()) + ", " +
                            shortest(o.rectangle.max().y()) + ") must be finite with a positive width and height");
    }
  }
}

double clamp01(double v) { return v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v); }

void blend(std::uint8_t* px, const Rgb& colour, double alpha) {
  if (alpha <= 0.0) return;
  for (int c = 0; c < 3; ++c) {
    const double v = (1.0 - alpha) * px[c] + alpha * colour[static_cast<std::size_t>(c)];
    px[c] = static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 255.0)));
  }
}

/// The robust scale: the 99th percentile of |f| over (a strided subset of) the finite pixel values.
double robustRange(const std::vector<float>& values) {
  const std::size_t stride = std::max<std::size_t>(1, values.size() / kRangeSamples);
  std::vector<float> a;
  a.reserve(values.size() / stride + 1);
  float maxAbs = 0.0f;
  for (std::size_t i = 0; i < values.size(); i += stride) {
    if (std::isfinite(values[i])) {
      a.push_back(std::fabs(values[i]));
      maxAbs = std::max(maxAbs, a.back());
    }
  }
  if (a.empty()) return 1.0;
  const auto k = static_cast<std::size_t>(0.99 * static_cast<double>(a.size() - 1));
  std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(k), a.end());
  double r = static_cast<double>(a[k]);
  if (!(r > 0.0)) r = static_cast<double>(maxAbs);
  return r > 0.0 ? r : 1.0;
}

/// Draws the level set {f = level} as an anti-aliased line of the given width: a pixel whose 3×3
/// neighbourhood straddles the level gets coverage from its estimated distance d (pixels) to the
/// level set, the smaller of |g|/|∇g| (central differences) and the linearly interpolated crossing
/// along the edges to its neighbours of the other sign.
void drawContour(Image& image, const std::vector<float>& values, double level, const Rgb& colour, double width) {
  const int w = image.width, h = image.height;
  auto g = [&](int x, int y) {
    return static_cast<double>(values[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) +
                                      static_cast<std::size_t>(x)]) - level;
  };
  const double reach = 0.5 * width + 0.5;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double gp = g(x, y);
      if (!std::isfinite(gp)) continue;
      const bool inside = gp > 0.0;
      double dEdge = gp == 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int qx = x + dx, qy = y + dy;
          if ((dx == 0 && dy == 0) || qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
          const double gq = g(qx, qy);
          if (!std::isfinite(gq) || (gq > 0.0) == inside) continue;
          const double t = std::fabs(gp) / std::fabs(gp - gq);
          dEdge = std::min(dEdge, t * ((dx != 0 && dy != 0) ? std::sqrt(2.0) : 1.0));
        }
      }
      if (!(dEdge < reach)) continue;
      const int x0 = std::max(0, x - 1), x1 = std::min(w - 1, x + 1);
      const int y0 = std::max(0, y - 1), y1 = std::min(h - 1, y + 1);
      const double gx = (g(x1, y) - g(x0, y)) / std::max(1, x1 - x0);
      const double gy = (g(x, y1) - g(x, y0)) / std::max(1, y1 - y0);
      const double grad = std::hypot(gx, gy);
      double d = dEdge;
      if (std::isfinite(grad) && grad > 0.0) d = std::min(d, std::fabs(gp) / grad);
      blend(image.at(x, y), colour, clamp01(reach - d));
    }
  }
}

}  // namespace

void validateSection(const ImplicitField& field, const SectionPlane& plane, const SectionOptions& options) {
  validateImpl(field, plane, options);
}

const char* sectionAxisName(int axis) noexcept {
  switch (axis) {
    case 0: return "x";
    case 1: return "y";
    case 2: return "z";
    default: return "?";
  }
}

SectionPlane SectionPlane::parse(std::string_view text) {
  const auto fail = [&]() -> SectionPlane {
    throw InvalidArgument("section plane '" + std::string(text) + "': expected x=VALUE, y=VALUE or z=VALUE");
  };
  std::size_t i = 0;
  auto skipBlanks = [&] {
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
  };
  skipBlanks();
  if (i >= text.size()) return fail();
  SectionPlane p;
  switch (text[i]) {
    case 'x': case 'X': p.axis = 0; break;
    case 'y': case 'Y': p.axis = 1; break;
    case 'z': case 'Z': p.axis = 2; break;
    default: return fail();
  }
  ++i;
  skipBlanks();
  if (i >= text.size() || text[i] != '=') return fail();
  ++i;
  skipBlanks();
  std::string number(text.substr(i));
  while (!number.empty() && (number.back() == ' ' || number.back() == '\t')) number.pop_back();
  char* end = nullptr;
  p.value = std::strtod(number.c_str(), &end);
  if (number.empty() || end != number.c_str() + number.size() || !std::isfinite(p.value)) return fail();
  return p;
}

std::string SectionPlane::toString() const { return std::string(sectionAxisName(axis)) + "=" + shortest(value); }

Eigen::Vector3d SectionResult::pixelCentre(int x, int y) const {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  p[plane.axis] = plane.value;
  p[plane.rightAxis()] = rectangle.min().x() + (x + 0.5) * pixelSize;
  p[plane.upAxis()] = rectangle.max().y() - (y + 0.5) * pixelSize;
  return p;
}

Eigen::Vector2d SectionResult::pixelOf(const Eigen::Vector3d& point) const {
  return {(point[plane.rightAxis()] - rectangle.min().x()) / pixelSize,
          (rectangle.max().y() - point[plane.upAxis()]) / pixelSize};
}

Rgb sectionColour(double f, double range, double gamma) noexcept {
  if (!std::isfinite(f)) return {128, 128, 128};
  const double t = range > 0.0 ? std::clamp(f / range, -1.0, 1.0) : (f > 0.0 ? 1.0 : (f < 0.0 ? -1.0 : 0.0));
  // Ends of the map: a saturated blue and red that keep black and coloured lines readable on them.
  static constexpr double kBlue[3] = {33.0, 82.0, 190.0};
  static constexpr double kRed[3] = {200.0, 30.0, 40.0};
  const double* end = t < 0.0 ? kBlue : kRed;
  const double a = gamma == 1.0 ? std::fabs(t) : std::pow(std::fabs(t), gamma);
  Rgb out{};
  for (std::size_t c = 0; c < 3; ++c) out[c] = static_cast<std::uint8_t>(std::lround(255.0 + a * (end[c] - 255.0)));
  return out;
}

Rgb sectionContourColour(std::size_t index) noexcept {
  static constexpr Rgb kPalette[] = {{0, 120, 40}, {120, 40, 170}, {230, 120, 0}, {0, 120, 140}, {120, 70, 20}};
  if (index == 0) return {0, 0, 0};
  return kPalette[(index - 1) % (sizeof kPalette / sizeof kPalette[0])];
}

Rgb sectionPointColour() noexcept { return {255, 220, 0}; }

SectionResult renderSection(const FieldEvaluator& evaluator, const ImplicitField& field, const SectionPlane& plane,
                            const SectionOptions& options) {
  validateImpl(field, plane, options);
  const auto start = std::chrono::steady_clock::now();
  const int right = plane.rightAxis(), up = plane.upAxis();
  const Eigen::AlignedBox3d& box = field.bounds();

  // The rectangle, then square pixels: the longer side gets `size` pixels.
  Eigen::AlignedBox2d rect = options.rectangle;
  if (rect.isEmpty()) {
    rect = Eigen::AlignedBox2d(Eigen::Vector2d(box.min()[right], box.min()[up]),
                               Eigen::Vector2d(box.max()[right], box.max()[up]));
    double longest = rect.sizes().maxCoeff();
    if (!(longest > 0.0)) longest = std::max(1e-12, box.sizes().maxCoeff());
    const Eigen::Vector2d grow = Eigen::Vector2d::Constant(options.margin * longest);
    rect = Eigen::AlignedBox2d(rect.min() - grow, rect.max() + grow);
    if (!(rect.sizes().minCoeff() > 0.0)) {  // a flat box without margin: at least one pixel across
      const Eigen::Vector2d pad = (rect.sizes().array() > 0.0).select(Eigen::Vector2d::Zero(),
                                                                      Eigen::Vector2d::Constant(0.5 * longest / options.size));
      rect = Eigen::AlignedBox2d(rect.min() - pad, rect.max() + pad);
    }
  }
  const Eigen::Vector2d extent = rect.sizes();
  int width = options.size, height = options.size;
  double pixel = 0.0;
  if (extent.x() >= extent.y()) {
    pixel = extent.x() / width;
    height = std::clamp(static_cast<int>(std::lround(extent.y() / pixel)), 1, kMaxSize);
  } else {
    pixel = extent.y() / height;
    width = std::clamp(static_cast<int>(std::lround(extent.x() / pixel)), 1, kMaxSize);
  }
  {
    const Eigen::Vector2d centre = rect.center();
    const Eigen::Vector2d half(0.5 * width * pixel, 0.5 * height * pixel);
    rect = Eigen::AlignedBox2d(centre - half, centre + half);
  }

  {
    // Per pixel: the float value, the RGB image and the PNG's filtered rows and compression buffers; plus one
    // batch of queries (24 bytes a point) and their values.
    const double pixels = static_cast<double>(width) * static_cast<double>(height);
    const double batch = static_cast<double>(std::min<std::size_t>(kBatchPoints, static_cast<std::size_t>(pixels)));
    requireMemory(options.limits, "section", 16.0 * pixels + 40.0 * batch,
                  "the " + std::to_string(width) + " x " + std::to_string(height) + " picture of " + plane.toString(),
                  "use a smaller --size");
  }
  SectionResult result;
  result.plane = plane;
  result.rectangle = rect;
  result.pixelSize = pixel;
  result.image = Image(width, height, 3, 255);

  // f at the pixel centres, in batches of whole rows.
  const std::size_t w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
  result.values.resize(w * h);
  const std::size_t rowsPerBatch = std::max<std::size_t>(1, kBatchPoints / w);
  Points queries;
  for (std::size_t row0 = 0; row0 < h; row0 += rowsPerBatch) {
    const std::size_t rows = std::min(rowsPerBatch, h - row0);
    queries.resize(static_cast<Eigen::Index>(rows * w), 3);
    for (std::size_t r = 0; r < rows; ++r) {
      for (std::size_t x = 0; x < w; ++x) {
        queries.row(static_cast<Eigen::Index>(r * w + x)) =
            result.pixelCentre(static_cast<int>(x), static_cast<int>(row0 + r)).transpose();
      }
    }
    const Eigen::VectorXd f = evaluator.evaluate(queries).values;
    for (Eigen::Index i = 0; i < f.size(); ++i) {
      result.values[row0 * w + static_cast<std::size_t>(i)] = static_cast<float>(f[i]);
    }
  }

  // Value statistics and the colour scale.
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const float v : result.values) {
    if (!std::isfinite(v)) continue;
    lo = std::min(lo, static_cast<double>(v));
    hi = std::max(hi, static_cast<double>(v));
  }
  result.minValue = std::isfinite(lo) ? lo : 0.0;
  result.maxValue = std::isfinite(hi) ? hi : 0.0;
  result.range = options.range > 0.0 ? options.range : robustRange(result.values);
  for (std::size_t y = 0; y < h; ++y) {
    for (std::size_t x = 0; x < w; ++x) {
      const Rgb c = sectionColour(static_cast<double>(result.values[y * w + x]), result.range, options.gamma);
      std::uint8_t* px = result.image.at(static_cast<int>(x), static_cast<int>(y));
      px[0] = c[0];
      px[1] = c[1];
      px[2] = c[2];
    }
  }

  // Contours: offsets first, the 0-level on top.
  result.levels.push_back(0.0);
  result.levels.insert(result.levels.end(), field.offsets().begin(), field.offsets().end());
  if (options.contours) {
    const int longest = std::max(width, height);
    const double lineWidth = options.lineWidth > 0.0 ? options.lineWidth : (longest > 1536 ? 2.0 : 1.5);
    for (std::size_t k = result.levels.size(); k-- > 0;) {
      drawContour(result.image, result.values, result.levels[k], sectionContourColour(k), lineWidth);
    }
  }

  // Points within the band, as anti-aliased dots.
  if (options.points.rows() > 0) {
    result.band = options.band > 0.0 ? options.band : 0.01 * box.sizes().maxCoeff();
    const double radius =
        options.dotRadius > 0.0 ? options.dotRadius : std::max(1.5, 1.5 * std::max(width, height) / 1024.0);
    const Rgb colour = sectionPointColour();
    const Rgb ring{40, 40, 40};  // a thin dark outline keeps the dots visible on white
    for (Eigen::Index i = 0; i < options.points.rows(); ++i) {
      const Eigen::Vector3d p = options.points.row(i).transpose();
      if (!p.allFinite() || !(std::fabs(p[plane.axis] - plane.value) < result.band)) continue;
      const Eigen::Vector2d c = result.pixelOf(p);
      const double outer = radius + 1.0;
      const int x0 = std::max(0, static_cast<int>(std::floor(c.x() - outer - 1.0)));
      const int x1 = std::min(width - 1, static_cast<int>(std::ceil(c.x() + outer + 1.0)));
      const int y0 = std::max(0, static_cast<int>(std::floor(c.y() - outer - 1.0)));
      const int y1 = std::min(height - 1, static_cast<int>(std::ceil(c.y() + outer + 1.0)));
      if (x0 > x1 || y0 > y1) continue;  // projects outside the image
      ++result.pointsDrawn;
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          const double d = std::hypot(x + 0.5 - c.x(), y + 0.5 - c.y());
          blend(result.image.at(x, y), ring, clamp01(outer + 0.5 - d));
          blend(result.image.at(x, y), colour, clamp01(radius + 0.5 - d));
        }
      }
    }
  }
  result.seconds = secondsSince(start);
  return result;
}

SectionResult renderSection(const Device& device, const ImplicitField& field, const SectionPlane& plane,
                            const SectionOptions& options) {
  validateImpl(field, plane, options);  // before building the evaluator
  const auto start = std::chrono::steady_clock::now();
  const FieldEvaluator evaluator(device, field, options.precision);
  const double setup = secondsSince(start);
  SectionResult result = renderSection(evaluator, field, plane, options);
  result.seconds += setup;
  return result;
}

}  // namespace duplexfit
