// Placing sliced layers on the build plate (slice.hpp): output = scale · model + translation in the
// output frame (x, y, z) = (u, v, build axis). Plate placement puts the lowest layer's bottom at z = 0 and
// centres the loops' (u, v) extent on the plate [0, W] × [0, D].
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "duplexfit/error.hpp"
#include "duplexfit/slice.hpp"

namespace duplexfit {

namespace {

std::string num(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

/// Rounds a length up to a whole number of steps (a length within 10⁻⁹ step of one counts as it).
double roundUp(double length, double step) {
  if (!(step > 0.0)) return length;
  return std::max(1.0, std::ceil(length / step - 1e-9)) * step;
}

}  // namespace

const char* slicePlaceName(SlicePlace place) noexcept { return place == SlicePlace::None ? "none" : "plate"; }

SlicePlace parseSlicePlace(const std::string& text) {
  if (text == "plate") return SlicePlace::Plate;
  if (text == "none") return SlicePlace::None;
  throw InvalidArgument("placement '" + text + "' (--place) is not 'plate' or 'none'");
}

double lengthUnitMillimetres(const std::string& name) {
  if (name == "mm") return 1.0;
  if (name == "in") return 25.4;
  if (name == "um") return 0.001;
  throw InvalidArgument("output units '" + name + "' (--units) are not mm, in or um; scale lengths with --scale");
}

Eigen::Vector2d parsePlateSize(const std::string& text) {
  const auto sep = text.find_first_of("xX,");
  const auto parse = [&](const std::string& part, double& out) {
    char* end = nullptr;
    out = std::strtod(part.c_str(), &end);
    return !part.empty() && end != part.c_str() && *end == '\0' && std::isfinite(out) && out > 0.0;
  };
  Eigen::Vector2d size;
  if (sep == std::string::npos || !parse(text.substr(0, sep), size.x()) || !parse(text.substr(sep + 1), size.y())) {
    throw InvalidArgument("plate size '" + text + "' (--plate) is not WxD with two positive numbers (e.g. 120x80)");
  }
  return size;
}

SlicePlacement placeSlices(const SliceResult& result, const PlacementOptions& options) {
  const double s = options.scale;
  if (!(s > 0.0) || !std::isfinite(s)) {
    throw InvalidArgument("slice placement: the scale must be > 0, got " + num(s));
  }
  if (!(options.plateStep >= 0.0) || !std::isfinite(options.plateStep)) {
    throw InvalidArgument("slice placement: the plate step must be >= 0, got " + num(options.plateStep));
  }
  const Eigen::Vector2d given = options.plate;
  const bool plateGiven = given.x() != 0.0 || given.y() != 0.0;
  if (plateGiven && !(given.x() > 0.0 && given.y() > 0.0 && given.allFinite())) {
    throw InvalidArgument("slice placement: the plate size must be two positive numbers, got " + num(given.x()) +
                          " x " + num(given.y()));
  }
  if (plateGiven && options.place == SlicePlace::None) {
    throw InvalidArgument("slice placement: a plate size needs placement 'plate' (--place plate)");
  }
  const int u = (result.axis + 1) % 3, v = (result.axis + 2) % 3;
  // The part in model plane coordinates: the loops' extent (the sliced box when there are no loops).
  Eigen::AlignedBox2d extent;
  for (const SliceLayer& layer : result.layers) {
    for (const SliceLoop& loop : layer.loops) {
      for (Eigen::Index i = 0; i < loop.points.rows(); ++i) {
        extent.extend(Eigen::Vector2d(loop.points(i, 0), loop.points(i, 1)));
      }
    }
  }
  if (extent.isEmpty()) {
    extent = Eigen::AlignedBox2d(Eigen::Vector2d(result.bounds.min()[u], result.bounds.min()[v]),
                                 Eigen::Vector2d(result.bounds.max()[u], result.bounds.max()[v]));
  }
  const double bottom = result.layers.empty() ? result.start : result.layers.front().height;
  const double top =
      result.layers.empty() ? result.start : result.layers.back().height + result.layers.back().thickness;

  SlicePlacement p;
  p.place = options.place;
  p.scale = s;
  p.plateGiven = plateGiven;
  p.lowestModel = bottom;
  const Eigen::Vector2d size = s * extent.sizes();
  if (options.place == SlicePlace::Plate) {
    Eigen::Vector2d plate = given;
    if (plateGiven) {
      const double tol = 1e-9 * std::max(plate.maxCoeff(), 1.0);
      if (size.x() > plate.x() + tol || size.y() > plate.y() + tol) {
        throw InvalidArgument("slice placement: the part (" + num(size.x()) + " x " + num(size.y()) +
                              " output units) is larger than the plate (" + num(plate.x()) + " x " + num(plate.y()) +
                              "; --plate WxD)");
      }
    } else {
      const double margin = 4.0 * result.grid * s;  // 2 grid steps on each side, as planeBox
      plate = Eigen::Vector2d(roundUp(size.x() + margin, options.plateStep),
                              roundUp(size.y() + margin, options.plateStep));
    }
    const Eigen::Vector2d centre = s * extent.center();
    p.translation = Eigen::Vector3d(0.5 * plate.x() - centre.x(), 0.5 * plate.y() - centre.y(), -s * bottom);
    p.plate = Eigen::AlignedBox2d(Eigen::Vector2d::Zero(), plate);
  } else {
    const Eigen::AlignedBox2d box = planeBox(result).extend(extent);
    const Eigen::Vector2d corner = s * box.min(), sz = s * box.sizes();
    const Eigen::Vector2d rounded(roundUp(sz.x(), options.plateStep), roundUp(sz.y(), options.plateStep));
    p.plate = Eigen::AlignedBox2d(corner, corner + rounded);
  }
  const Eigen::Vector2d t2 = p.translation.head<2>();
  const Eigen::Vector2d lo = s * extent.min() + t2, hi = s * extent.max() + t2;
  p.part = Eigen::AlignedBox3d(Eigen::Vector3d(lo.x(), lo.y(), s * bottom + p.translation.z()),
                               Eigen::Vector3d(hi.x(), hi.y(), s * top + p.translation.z()));
  return p;
}

SliceResult applyPlacement(const SliceResult& result, const SlicePlacement& placement) {
  const double s = placement.scale;
  const Eigen::Vector2d t2(placement.translation.x(), placement.translation.y());
  const double tz = placement.translation.z();
  SliceResult r = result;
  for (SliceLayer& layer : r.layers) {
    layer.height = s * layer.height + tz;
    layer.thickness *= s;
    layer.rawThickness *= s;  // ∞ stays ∞
    layer.area *= s * s;
    for (SliceLoop& loop : layer.loops) {
      for (Eigen::Index i = 0; i < loop.points.rows(); ++i) {
        loop.points(i, 0) = s * loop.points(i, 0) + t2.x();
        loop.points(i, 1) = s * loop.points(i, 1) + t2.y();
      }
      loop.area *= s * s;
    }
  }
  r.cusp *= s;
  r.minLayer *= s;
  r.maxLayer *= s;
  r.layer *= s;
  r.grid *= s;
  r.start = s * r.start + tz;
  r.end = s * r.end + tz;
  const int u = (result.axis + 1) % 3, v = (result.axis + 2) % 3, a = result.axis;
  Eigen::Vector3d lo, hi;
  lo[u] = placement.part.min().x();
  lo[v] = placement.part.min().y();
  lo[a] = placement.part.min().z();
  hi[u] = placement.part.max().x();
  hi[v] = placement.part.max().y();
  hi[a] = placement.part.max().z();
  r.bounds = Eigen::AlignedBox3d(lo, hi);
  return r;
}

}  // namespace duplexfit
