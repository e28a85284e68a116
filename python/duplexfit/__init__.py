"""duplexfit: one implicit field for a surface and its offset surfaces, fitted to an oriented point cloud.

The zero level {f = 0} of the fitted field is the surface, each level {f = delta} an offset surface
(delta > 0 inward); f is positive inside and about the signed distance near the surface. The fit runs on an
OpenCL device (or the plain C++ reference device).

    import numpy as np, duplexfit
    points, normals = duplexfit.read_point_cloud("cloud.ply")
    field = duplexfit.fit(points, normals, offsets=[0.02])
    f = field.value(points)                     # (N,)  about 0
    g = field.gradient(points)                  # (N, 3), pointing inward
    v, t = field.mesh(0.0)                      # vertices (V, 3) float64, faces (F, 3) int32
    duplexfit.write_mesh("zero.ply", v, t)
    duplexfit.write_mesh("offset.ply", *field.mesh(0.02))

Long calls release the GIL and take progress=callable(stage, fraction, message): fraction in [0, 1] or None,
called from the calling thread; returning False (or raising) cancels the call with duplexfit.Cancelled
(a raised exception is its __cause__); Ctrl-C raises KeyboardInterrupt. Library errors are
duplexfit.InvalidArgument (a ValueError), IoError (an OSError), DeviceError, BuildError, all duplexfit.Error.
"""

from . import _duplexfit as _native
from ._duplexfit import (
    BuildError,
    Cancelled,
    Device,
    DeviceError,
    DeviceInfo,
    Error,
    Field,
    InvalidArgument,
    IoError,
    PipelineResult,
    __version__,
    devices,
    load_field,
    mesh_topology,
    read_mesh,
    read_point_cloud,
    simplification_available,
    write_mesh,
    write_point_cloud,
)

__all__ = [
    "BuildError", "Cancelled", "Device", "DeviceError", "DeviceInfo", "Error", "Field", "InvalidArgument",
    "IoError", "PipelineResult", "__version__", "devices", "fit", "load_field", "mesh_topology", "read_mesh",
    "read_point_cloud", "run_pipeline", "simplification_available", "write_mesh", "write_point_cloud",
]

_D = _native._fit_defaults()


def _offsets(offsets):
    if offsets is None:
        return []
    if isinstance(offsets, (int, float)):
        return [float(offsets)]
    return [float(d) for d in offsets]


def fit(points, normals, offsets=(), *, device=None, progress=None, levels=None,
        offsets_relative=_D["offsets_relative"], normals_inward=_D["normals_inward"],
        alpha=_D["alpha"], smoothing=_D["smoothing"], fit_tolerance=_D["fit_tolerance"],
        validity_tolerance=_D["validity_tolerance"], merge_distance=_D["merge_distance"],
        side_test=_D["side_test"], crease_test=_D["crease_test"], sign_anchors=_D["sign_anchors"],
        medial_constraints=_D["medial_constraints"], overshoot_check=_D["overshoot_check"],
        offset_correction=_D["offset_correction"],
        drop_zero_normal_points=_D["drop_zero_normal_points"], precision=_D["precision"],
        preconditioner=_D["preconditioner"], fsai_threshold=_D["fsai_threshold"],
        assembly=_D["assembly"], level_tolerance=_D["level_tolerance"],
        coarse_tolerance=_D["coarse_tolerance"], max_iterations=_D["max_iterations"],
        relative_tolerance=_D["relative_tolerance"], merge_duplicates=True):
    """Fits the field to an oriented cloud and returns a duplexfit.Field.

    points, normals: (N, 3) arrays of numbers (any layout; copied as float64). Normals point out of the
        solid unless normals_inward; zero rows are points without a normal.
    offsets: the offsets delta in input units (fractions of the largest side with offsets_relative),
        > 0 inward, < 0 outward; a number or a sequence.
    device: None (Device.default()), a duplexfit.Device or a spec string ("cpu", "gpu", "ref", "P:D";
        each spec is opened once and reused, like Device.default()).
    progress: None or callable(stage, fraction, message); return False to cancel.
    levels: number of levels M (None: from the cloud). precision: "float" or "double".
    preconditioner: "fsai" (default), "block-jacobi" or "jacobi"; fsai_threshold: FSAI's coupling threshold.
    assembly: where the level matrices are assembled, "auto" (default: the device when it is a GPU), "host"
        or "device" (an OpenCL device with double precision); the same matrices either way.
    The other keywords are the library's FitOptions (docs/method.md), with its defaults; smoothing > 0
    approximates noisy data instead of interpolating. merge_duplicates: merge points with identical
    positions first (their normals averaged).
    The result's .report holds the fit's report (levels, CG iterations, e0, e_delta, seconds).
    """
    options = dict(locals())
    for name in ("points", "normals", "device", "progress"):
        del options[name]
    options["offsets"] = _offsets(offsets)
    return _native._fit(points, normals, options, device, progress)


def run_pipeline(source, normals=None, offsets=(), *, device=None, progress=None, out_dir=None,
                 mesh_format="ply", separate=False, estimate_normals=False, denoise=False,
                 denoise_when_noisy=True, denoise_smoothing=0.2, remove_outliers=False, cell=None,
                 resolution=None, clean=True, max_triangles=0,
                 max_error=0.0, **fit_options):
    """The whole job of `duplexfit fit` and returns a duplexfit.PipelineResult.

    source: a cloud file (PLY or XYZ) or an (N, 3) array of points with normals (or estimate_normals).
    The cloud is read, duplicates merged, (normals estimated, denoised), fitted, its level sets extracted,
    cleaned (small offset components dropped) and self-checked. result.meshes lists (vertices, faces) of
    the zero level then of each offset; result.field is the field; result.report is report.json's
    content. With out_dir, result.write(out_dir, mesh_format) is called (zero.ply, offset1.ply, ...,
    field.dpxf, report.json). separate: the separate-fit baseline. cell / resolution: the marching grid
    (default sigma_M/2). max_triangles / max_error: simplification (needs meshoptimizer).
    denoise: the bilateral filter; a filtered cloud is fitted with smoothing denoise_smoothing (when
    smoothing is 0). denoise_when_noisy: a cloud whose noise estimate says noisy
    (report["preprocessing"]["noise"]) is filtered all the same. The other
    keywords are those of fit() (merge_duplicates excepted: the pipeline always merges).
    """
    options = dict(fit_options)
    options.update(offsets=_offsets(offsets), separate=separate, estimate_normals=estimate_normals,
                   denoise=denoise, denoise_when_noisy=denoise_when_noisy, denoise_smoothing=denoise_smoothing,
                   remove_outliers=remove_outliers, cell=cell, resolution=resolution,
                   clean=clean, max_triangles=max_triangles, max_error=max_error)
    result = _native._run_pipeline(source, normals, options, device, progress)
    if out_dir is not None:
        result.write(out_dir, mesh_format)
    return result
