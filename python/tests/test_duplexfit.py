"""Tests of the Python package duplexfit (ctest: python; run by Debian's python3 with PYTHONPATH=build/python).

An analytic sphere (radius 0.5, Fibonacci lattice, outward normals) is fitted once with the inward offset
0.05; the field, its gradient and its meshes are compared with the exact answers: f = 0.5 - |x| near the
surface, so f = 0 on the sphere and f = 0.05 at radius 0.45. Exits with 77 (Skipped) without numpy.
"""

import os
import pathlib
import signal
import sys
import tempfile
import threading
import time
import unittest

try:
    import numpy as np
except ImportError:
    print("SKIPPED: numpy is not installed (Debian: python3-numpy)")
    sys.exit(77)

import duplexfit

RADIUS = 0.5
DELTA = 0.05


def sphere(n, radius=RADIUS):
    """n points of a Fibonacci lattice on the sphere, and their outward unit normals."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1.0 - 2.0 * i / n)
    theta = np.pi * (1.0 + 5.0 ** 0.5) * i
    d = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    return radius * d, d


def random_directions(n, seed=1):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1)[:, None]


class SphereFit(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.points, cls.normals = sphere(3000)
        cls.events = []
        start = time.perf_counter()
        cls.field = duplexfit.fit(cls.points, cls.normals, [DELTA],
                                  progress=lambda *event: cls.events.append(event))
        cls.fit_seconds = time.perf_counter() - start
        cls.directions = random_directions(2000)

    def test_report(self):
        r = self.field.report
        self.assertEqual(r["input_points"], 3000)
        self.assertEqual(r["offsets"], [DELTA])
        self.assertTrue(r["converged"])
        self.assertEqual(self.field.levels, r["levels"])
        self.assertEqual(len(r["level_reports"]), r["levels"])
        self.assertLess(r["e0"], 1e-4)
        self.assertTrue(r["preconditioner"].startswith("fsai"), r["preconditioner"])
        self.assertEqual(self.field.offsets, [DELTA])
        lo, hi = self.field.bounds
        np.testing.assert_allclose(lo, self.points.min(axis=0))
        np.testing.assert_allclose(hi, self.points.max(axis=0))
        self.assertEqual(len(self.field.sigmas), self.field.levels)
        self.assertGreater(self.field.sigmas[0], self.field.sigmas[-1])
        print(f"\nfit of {len(self.points)} points: {self.fit_seconds:.2f} s, {self.field}")

    def test_block_jacobi_on_request(self):
        field = duplexfit.fit(self.points, self.normals, [DELTA], preconditioner="block-jacobi", levels=3)
        self.assertEqual(field.report["preconditioner"], "block-jacobi-16")
        self.assertTrue(field.report["converged"])

    def test_assembly_on_the_device_on_request(self):
        host = duplexfit.fit(self.points, self.normals, [DELTA], assembly="host", levels=3)
        self.assertEqual(host.report["assembly"], "host")
        device = duplexfit.fit(self.points, self.normals, [DELTA], assembly="device", levels=3)
        # The device assembles where it has double precision (the reference device never does); the same
        # matrices either way, so the same field.
        self.assertIn(device.report["assembly"], ("host", "device"))
        np.testing.assert_array_equal(host.value(self.points), device.value(self.points))
        with self.assertRaisesRegex(duplexfit.InvalidArgument, "assembly"):
            duplexfit.fit(self.points, self.normals, assembly="gpu")

    def test_zero_level_at_the_sphere(self):
        # New points on the sphere, not the fitted ones.
        f = self.field.value(RADIUS * self.directions)
        self.assertEqual(f.shape, (len(self.directions),))
        self.assertEqual(f.dtype, np.float64)
        self.assertLess(np.abs(f).max(), 1e-3)

    def test_offset_level_at_the_offset_sphere(self):
        f = self.field.value((RADIUS - DELTA) * self.directions)
        self.assertLess(np.abs(f - DELTA).max(), 0.02 * DELTA)

    def test_sign_inside_and_outside(self):
        self.assertGreater(self.field.value([[0.0, 0.0, 0.0]])[0], 0.0)
        self.assertLess(self.field.value([[0.0, 0.0, 0.58]])[0], -0.05)
        self.assertTrue(np.array_equal(self.field([[0.1, 0.2, 0.3]]), self.field.value([[0.1, 0.2, 0.3]])))

    def test_gradient_is_the_inward_radial_direction(self):
        x = RADIUS * self.directions
        g = self.field.gradient(x)
        self.assertEqual(g.shape, x.shape)
        norm = np.linalg.norm(g, axis=1)
        self.assertLess(np.abs(norm - 1.0).max(), 0.05)
        cosine = np.sum(g / norm[:, None] * -self.directions, axis=1)
        self.assertGreater(cosine.min(), 0.999)
        values, gradients = self.field.value_and_gradient(x)
        np.testing.assert_allclose(values, self.field.value(x), rtol=0, atol=1e-6)
        np.testing.assert_allclose(gradients, g, rtol=0, atol=1e-6)

    def test_meshes_of_both_levels(self):
        for iso, radius in ((0.0, RADIUS), (DELTA, RADIUS - DELTA)):
            with self.subTest(iso=iso):
                vertices, faces = self.field.mesh(iso, resolution=64)
                self.assertEqual(vertices.dtype, np.float64)
                self.assertEqual(faces.dtype, np.int32)
                self.assertEqual(vertices.shape[1], 3)
                self.assertEqual(faces.shape[1], 3)
                self.assertGreater(len(faces), 1000)
                r = np.linalg.norm(vertices, axis=1)
                self.assertLess(np.abs(r - radius).max(), 2e-3)
                t = duplexfit.mesh_topology(vertices, faces)
                self.assertTrue(t["watertight"] and t["manifold"] and t["oriented"])
                self.assertEqual(t["components"], 1)
                self.assertEqual(t["euler_characteristic"], 2)
                # Outward oriented: the first face's normal points away from the centre.
                a, b, c = vertices[faces[0]]
                self.assertGreater(np.dot(np.cross(b - a, c - a), a), 0.0)

    def test_progress_events(self):
        stages = {stage for stage, _, _ in self.events}
        self.assertTrue({"hierarchy", "constraints", "assembly", "solve"} <= stages, stages)
        fractions = [f for _, f, _ in self.events if f is not None]
        self.assertTrue(fractions)
        self.assertTrue(all(0.0 <= f <= 1.0 for f in fractions))
        self.assertEqual(fractions, sorted(fractions))
        self.assertTrue(any(m.startswith("level 1/") for _, _, m in self.events))

    def test_save_load_roundtrip(self):
        x = np.concatenate([RADIUS * self.directions[:500], 0.3 * self.directions[500:1000]])
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "sphere.dpxf")
            self.field.save(path)
            loaded = duplexfit.load_field(path)
        self.assertIsNone(loaded.report)
        self.assertEqual(loaded.offsets, self.field.offsets)
        self.assertEqual(loaded.levels, self.field.levels)
        self.assertEqual(loaded.centres, self.field.centres)
        self.assertTrue(np.array_equal(loaded.value(x), self.field.value(x)))
        self.assertTrue(np.array_equal(loaded.gradient(x), self.field.gradient(x)))

    def test_reference_device_agrees(self):
        x = RADIUS * self.directions[:200]
        ref = self.field.value(x, device="ref")
        self.assertTrue(duplexfit.Device("ref").is_reference)
        np.testing.assert_allclose(ref, self.field.value(x, device=duplexfit.Device.default()), rtol=0, atol=1e-5)

    def test_non_contiguous_and_integer_inputs(self):
        x = np.asfortranarray(RADIUS * self.directions[:100])
        strided = np.repeat(x, 2, axis=0)[::2]
        expected = self.field.value(np.ascontiguousarray(x))
        self.assertFalse(strided.flags.c_contiguous)
        self.assertTrue(np.array_equal(self.field.value(x), expected))
        self.assertTrue(np.array_equal(self.field.value(strided), expected))
        self.assertTrue(np.array_equal(self.field.value(x.tolist()), expected))
        self.assertEqual(self.field.value(np.zeros((2, 3), dtype=np.int32)).shape, (2,))
        self.assertEqual(self.field.value(np.zeros((0, 3))).shape, (0,))
        self.assertEqual(self.field.gradient(np.zeros((0, 3))).shape, (0, 3))

    def test_evaluations_from_threads(self):
        x = np.random.default_rng(2).uniform(-0.6, 0.6, size=(50000, 3))
        expected = self.field.value(x)
        results = [None] * 4

        def work(i):
            results[i] = self.field.value(x)

        threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        self.assertTrue(all(np.array_equal(r, expected) for r in results))

    def test_bad_shapes_and_dtypes(self):
        p, n = self.points, self.normals
        cases = [
            (lambda: duplexfit.fit(p[:, :2], n), "points must have shape (N, 3); got shape (3000, 2)"),
            (lambda: duplexfit.fit(p, n[:-1]), "3000 points and 2999 normals"),
            (lambda: duplexfit.fit(p.ravel(), n), "got shape (9000,)"),
            (lambda: duplexfit.fit(p.astype(str), n), "got dtype <U"),
            (lambda: self.field.value(np.zeros((4, 2))), "points must have shape (N, 3)"),
            (lambda: self.field.gradient(np.zeros((2, 3, 1))), "got shape (2, 3, 1)"),
            (lambda: duplexfit.write_mesh("x.ply", np.zeros((3, 3)), np.zeros((1, 3))), "faces must be"),
            (lambda: duplexfit.write_mesh("x.ply", np.zeros((3, 3)), [[0, 1, -2]]), "face 0"),
        ]
        for call, message in cases:
            with self.subTest(message=message):
                with self.assertRaises(ValueError) as caught:
                    call()
                self.assertIn(message, str(caught.exception))

    def test_library_errors_carry_the_library_message(self):
        with self.assertRaises(duplexfit.InvalidArgument) as caught:
            duplexfit.fit(self.points[:5], self.normals[:5])
        self.assertIsInstance(caught.exception, ValueError)
        self.assertIn("points", str(caught.exception))
        bad = self.points.copy()
        bad[7, 1] = np.nan
        with self.assertRaisesRegex(duplexfit.InvalidArgument, "point 7 is not finite"):
            duplexfit.fit(bad, self.normals)
        with self.assertRaisesRegex(duplexfit.InvalidArgument, "precision"):
            duplexfit.fit(self.points, self.normals, precision="half")
        with self.assertRaisesRegex(duplexfit.InvalidArgument, "preconditioner"):
            duplexfit.fit(self.points, self.normals, preconditioner="ilu")
        with tempfile.TemporaryDirectory() as tmp:
            missing = os.path.join(tmp, "missing.dpxf")
            with self.assertRaises(duplexfit.IoError) as caught:
                duplexfit.load_field(missing)
            self.assertIsInstance(caught.exception, OSError)
            self.assertIn(missing, str(caught.exception))
            truncated = os.path.join(tmp, "truncated.dpxf")
            self.field.save(truncated)
            with open(truncated, "r+b") as f:
                f.truncate(100)
            with self.assertRaisesRegex(duplexfit.IoError, "truncated.dpxf"):
                duplexfit.load_field(truncated)
        with self.assertRaises(duplexfit.DeviceError) as caught:
            duplexfit.Device("no-such-device-anywhere")
        self.assertIn("no-such-device-anywhere", str(caught.exception))
        with self.assertRaises(TypeError):
            duplexfit.fit(self.points, self.normals, progress=42)
        with self.assertRaises(TypeError):
            duplexfit.fit(self.points, self.normals, device=3)


class Cancellation(unittest.TestCase):
    points, normals = sphere(1500)

    def test_callback_returning_false_cancels(self):
        calls = []

        def progress(stage, fraction, message):
            calls.append(stage)
            return False

        with self.assertRaises(duplexfit.Cancelled) as caught:
            duplexfit.fit(self.points, self.normals, [DELTA], progress=progress)
        self.assertIn("progress callback returned False", str(caught.exception))
        self.assertEqual(len(calls), 1)  # nothing is called after the cancellation

    def test_cancel_during_the_solve(self):
        def progress(stage, fraction, message):
            return stage != "solve"

        with self.assertRaisesRegex(duplexfit.Cancelled, "solve"):
            duplexfit.fit(self.points, self.normals, progress=progress)

    def test_callback_raising_cancels_with_the_cause(self):
        def progress(stage, fraction, message):
            raise ZeroDivisionError("stop here")

        with self.assertRaises(duplexfit.Cancelled) as caught:
            duplexfit.fit(self.points, self.normals, progress=progress)
        self.assertIsInstance(caught.exception, duplexfit.Error)
        self.assertIsInstance(caught.exception.__cause__, ZeroDivisionError)
        self.assertIn("raised", str(caught.exception))

    def test_keyboard_interrupt_in_the_callback_stays_one(self):
        def progress(stage, fraction, message):
            signal.raise_signal(signal.SIGINT)  # Ctrl-C: Python's handler raises KeyboardInterrupt here

        with self.assertRaises(KeyboardInterrupt):
            duplexfit.fit(self.points, self.normals, progress=progress)

    def test_cancel_a_mesh(self):
        field = duplexfit.fit(self.points, self.normals)
        stages = []

        def progress(stage, fraction, message):
            stages.append(stage)
            return fraction is None or fraction < 0.5

        with self.assertRaises(duplexfit.Cancelled):
            field.mesh(0.0, resolution=48, progress=progress)
        self.assertEqual(stages[0], "mesh")
        self.assertIn("polygonize", stages)
        v, f = field.mesh(0.0, resolution=48)  # the field still works afterwards
        self.assertGreater(len(f), 0)


class Pipeline(unittest.TestCase):
    def test_run_pipeline_on_arrays_and_write(self):
        points, normals = sphere(1500)
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "out")
            result = duplexfit.run_pipeline(points, normals, offsets=DELTA, resolution=48, out_dir=out)
            self.assertEqual(sorted(os.listdir(out)), ["field.dpxf", "offset1.ply", "report.json", "zero.ply"])
            self.assertTrue(result.converged)
            self.assertEqual(len(result.meshes), 2)
            for (vertices, faces), radius in zip(result.meshes, (RADIUS, RADIUS - DELTA)):
                self.assertLess(np.abs(np.linalg.norm(vertices, axis=1) - radius).max(), 3e-3)
            s = result.surfaces[1]
            self.assertEqual(s["offset"], DELTA)
            self.assertTrue(s["topology"]["watertight"])
            self.assertEqual(s["float32_degenerate"], 0)
            self.assertTrue(s["sound"])
            report = result.report
            self.assertEqual(report["points"], 1500)
            self.assertEqual(report["mode"], "duplex")
            self.assertEqual(report["offsets"], [DELTA])
            v, f = duplexfit.read_mesh(os.path.join(out, "zero.ply"))
            self.assertEqual(f.shape, result.meshes[0][1].shape)
            np.testing.assert_allclose(v, result.meshes[0][0], atol=1e-6)  # written as float32
            loaded = duplexfit.load_field(os.path.join(out, "field.dpxf"))
            x = points[:100]
            np.testing.assert_allclose(loaded.value(x), result.field.value(x), atol=1e-6)

    def test_duplicates_are_merged(self):
        points, normals = sphere(1000)
        spec = duplexfit.devices()[0].spec  # the first OpenCL device, else "ref"
        field = duplexfit.fit(np.vstack([points, points[:10]]), np.vstack([normals, normals[:10]]), device=spec)
        self.assertEqual(field.report["duplicates_merged"], 10)
        self.assertEqual(field.report["input_points"], 1000)
        self.assertEqual(field.device.spec, spec)
        again = duplexfit.fit(points, normals, device=spec)
        self.assertEqual(again.device, field.device)  # a spec string is opened once and reused

    def test_run_pipeline_on_a_file(self):
        points, normals = sphere(1500)
        with tempfile.TemporaryDirectory() as tmp:
            path = pathlib.Path(tmp) / "cloud.ply"
            duplexfit.write_point_cloud(path, points, normals)
            p, n = duplexfit.read_point_cloud(path)
            np.testing.assert_allclose(p, points, atol=1e-6)  # float32 in the file
            np.testing.assert_allclose(n, normals, atol=1e-6)
            result = duplexfit.run_pipeline(path, offsets=[DELTA], resolution=32)
            self.assertEqual(result.report["input"], str(path))
            self.assertEqual(len(result.meshes), 2)
            with self.assertRaisesRegex(ValueError, "normals are given with the points"):
                duplexfit.run_pipeline(path, normals)

    def test_run_pipeline_estimating_the_normals(self):
        points, _ = sphere(1500)
        with self.assertRaisesRegex(ValueError, "estimate_normals"):
            duplexfit.run_pipeline(points)
        result = duplexfit.run_pipeline(points, estimate_normals=True, resolution=32)
        vertices, _ = result.meshes[0]
        self.assertLess(np.abs(np.linalg.norm(vertices, axis=1) - RADIUS).max(), 3e-3)
        self.assertGreater(result.field.value([[0.0, 0.0, 0.0]])[0], 0.0)  # normals oriented outward
        with self.assertRaisesRegex(TypeError, "unexpected option 'bogus'"):
            duplexfit.run_pipeline(points, estimate_normals=True, bogus=1)

    def test_run_pipeline_denoises_a_noisy_cloud_unless_told_not_to(self):
        points, normals = sphere(1000)
        spacing = np.sqrt(4.0 * np.pi * RADIUS ** 2 / len(points))
        rng = np.random.default_rng(3)
        noisy = points + rng.normal(scale=0.8 * spacing, size=points.shape)  # per coordinate
        common = dict(offsets=[DELTA], resolution=32)
        auto = duplexfit.run_pipeline(noisy, normals, **common).report
        self.assertTrue(auto["preprocessing"]["noise"]["noisy"])
        self.assertEqual(auto["preprocessing"]["denoise"]["reason"], "noisy input (the noise estimate)")
        self.assertAlmostEqual(auto["smoothing"], 0.2)
        plain = duplexfit.run_pipeline(noisy, normals, denoise_when_noisy=False, **common).report
        self.assertIsNone(plain["preprocessing"]["denoise"])
        self.assertEqual(plain["smoothing"], 0.0)
        clean = duplexfit.run_pipeline(points, normals, **common).report
        self.assertFalse(clean["preprocessing"]["noise"]["noisy"])
        self.assertIsNone(clean["preprocessing"]["denoise"])
        asked = duplexfit.run_pipeline(points, normals, denoise=True, denoise_smoothing=0.1, **common).report
        self.assertEqual(asked["preprocessing"]["denoise"]["reason"], "asked (--denoise)")
        self.assertAlmostEqual(asked["smoothing"], 0.1)


class Devices(unittest.TestCase):
    def test_devices(self):
        listed = duplexfit.devices()
        self.assertEqual(listed[-1].spec, "ref")
        self.assertTrue(all(d.type in ("cpu", "gpu", "accelerator", "other") for d in listed))
        device = duplexfit.Device(listed[0].spec)
        self.assertEqual(device.spec, listed[0].spec)
        self.assertEqual(duplexfit.Device.default(), duplexfit.Device.default())  # opened once
        self.assertEqual(duplexfit.Device("ref"), duplexfit.Device.reference())
        self.assertIn(device.spec, repr(device))
        self.assertTrue(duplexfit.Device.reference().supports_double)


if __name__ == "__main__":
    unittest.main()
