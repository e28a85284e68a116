// SLA print packages in the layout of PrusaSlicer's SL1 archive (docs/method.md §10.7): one zip holding
// config.ini (the job as the printer reads it), prusaslicer.ini (the printer, material and print settings),
// one 8-bit grey PNG per layer at the display's resolution (<jobDir>00000.png, ...) and thumbnails
// (thumbnail/thumbnail<W>x<H>.png). The zip is written with libzip, an optional build component
// (sl1Available()). The layers are those of a placed SliceResult (applyPlacement), in millimetres, on a
// plate that is the display: [0, displayWidth] × [0, displayHeight].
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/image.hpp"
#include "duplexfit/slice.hpp"

namespace duplexfit {

/// display_orientation: how the plate's (x, y) map to the images' columns and rows.
enum class Sl1Orientation {
  Landscape,  ///< columns along x (display_pixels_x wide), rows along y
  Portrait    ///< columns along y, rows along x: the images are display_pixels_y wide, display_pixels_x tall
};
/// "landscape" / "portrait"; parseSl1Orientation throws InvalidArgument naming the text.
const char* sl1OrientationName(Sl1Orientation orientation) noexcept;
Sl1Orientation parseSl1Orientation(const std::string& text);

/// The printer: PrusaSlicer's printer settings that shape the package. The defaults are those of the
/// Original Prusa SL1 profile: a 120.96 × 68.04 mm display of 2560 × 1440 pixels (0.04725 mm), portrait,
/// mirrored in x.
struct Sl1Printer {
  std::string model = "SL1";                     ///< printer_model / printerModel
  std::string profile = "Original Prusa SL1";    ///< printer_settings_id / printerProfile
  std::string variant = "default";               ///< printer_variant / printerVariant
  double displayWidth = 120.96;   ///< display_width (mm): the plate's x extent
  double displayHeight = 68.04;   ///< display_height (mm): the plate's y extent
  int pixelsX = 2560;             ///< display_pixels_x: pixels along x
  int pixelsY = 1440;             ///< display_pixels_y: pixels along y
  Sl1Orientation orientation = Sl1Orientation::Portrait;
  bool mirrorX = true, mirrorY = false;  ///< display_mirror_x, display_mirror_y
  double maxPrintHeight = 150.0;  ///< max_print_height (mm)
  double fastTiltTime = 5.0, slowTiltTime = 8.0;  ///< s per layer (the print time estimate)
  double areaFill = 50.0;  ///< % of the display: a layer exposing more is a slow-tilt layer (numSlow)
  /// The pixel (mm): displayWidth / pixelsX (== displayHeight / pixelsY, checked by validateSl1Options).
  double pixel() const noexcept { return displayWidth / pixelsX; }
};

/// A package's print settings.
struct Sl1Options {
  Sl1Printer printer;
  double exposure = 10.0;         ///< expTime (s), PrusaSlicer's default exposure_time
  double initialExposure = 15.0;  ///< expTimeFirst (s), PrusaSlicer's default initial_exposure_time
  int fadeLayers = 10;            ///< numFade: layers fading from expTimeFirst to expTime (PrusaSlicer: 3..20)
  std::string materialName = "duplexfit";  ///< materialName / sla_material_settings_id
  std::string printProfile = "duplexfit";  ///< printProfile / sla_print_settings_id
  /// jobDir, the layer images' name prefix; empty: the package file's name without its extension.
  std::string jobName;
  /// Thumbnails (width × height pixels each); PrusaSlicer's SL1 profile asks for 400x400 and 800x480.
  std::vector<std::pair<int, int>> thumbnails = {{400, 400}, {800, 480}};
  bool hollow = false;  ///< config.ini's hollow flag (the layers are a hollowed shell)
};

/// @throws InvalidArgument naming the CLI option ("--sl1-display", "--sl1-pixels", "--exposure",
/// "--initial-exposure", "--fade-layers") for a bad value, non-square pixels or an unusable job name.
void validateSl1Options(const Sl1Options& options);
/// True when this build writes SL1 packages (it was built with libzip, Debian: libzip-dev).
bool sl1Available() noexcept;

/// What a package holds.
struct Sl1Summary {
  std::string jobName;
  std::size_t layers = 0;
  double layerHeight = 0.0;          ///< mm
  double pixel = 0.0;                ///< mm
  int imageWidth = 0, imageHeight = 0;  ///< the layer images' pixels (after the orientation)
  std::vector<double> exposedArea;   ///< per layer: white pixels · pixel² (mm²)
  std::size_t numFast = 0, numSlow = 0;
  double printTime = 0.0;            ///< s: the estimate written as printTime
  double usedMaterial = 0.0;         ///< ml: Σ exposed area · layer height
  std::vector<std::string> entries;  ///< the zip's entry names, in order
  std::size_t bytes = 0;             ///< the package's size
};

/// The display image of one placed layer (mm, plate [0, displayWidth] × [0, displayHeight]): 255 where a
/// pixel's centre lies inside the region. A plate point (x, y) lands in pixel (i, j) = (⌊x/p⌋, ⌊y/p⌋) of the
/// display, p = printer.pixel(), and that pixel is image column/row
///   landscape: (mirrorX ? Nx−1−i : i,  mirrorY ? j : Ny−1−j)
///   portrait:  (mirrorX ? j : Ny−1−j,  mirrorY ? i : Nx−1−i)
/// (PrusaSlicer's raster transform: portrait swaps the axes and flips x; row 0 is the image's top).
/// @throws InvalidArgument for bad printer settings.
Image sl1LayerImage(const SliceLayer& layer, const Sl1Printer& printer);

/// Writes the package of `placed` (uniform layers in mm, on the display's plate) to `path` through an
/// AtomicFile. Layer k's image is its region at its bottom height (the contour that CLI and masks hold).
/// @throws InvalidArgument (no libzip in this build, bad options, adaptive or empty layers, a part outside
/// the display or taller than max_print_height: each message names `path`), IoError naming `path`.
Sl1Summary writeSl1(const std::string& path, const SliceResult& placed, const Sl1Options& options);

}  // namespace duplexfit
