"""ctest python_example: runs python/examples/fit_sphere.py (the README's example) on the shared cloud
sphere_10k and checks the meshes it writes against the exact spheres (radius 0.5 and 0.45). Skips (77)
without numpy or without the shared data, except in CI (CI=true), where missing data fails.
"""

import os
import subprocess
import sys

try:
    import numpy as np
except ImportError:
    print("SKIPPED: numpy is not installed (Debian: python3-numpy)")
    sys.exit(77)

import duplexfit

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.environ.get("DUPLEXFIT_SOURCE_DIR", os.path.join(HERE, "..", ".."))
DATA = os.environ.get("DUPLEXFIT_SHARED_DATA") or os.path.join(SOURCE, "..", "shared", "data")
CLOUD = os.path.normpath(os.path.join(DATA, "clouds", "sphere_10k.ply"))


def main():
    if not os.path.isfile(CLOUD):
        if os.environ.get("CI") == "true":
            print(f"FAILED: {CLOUD} not found (the shared data is required in CI)")
            return 1
        print(f"SKIPPED: {CLOUD} not found (the shared data)")
        return 77
    out = os.environ.get("PYTHON_EXAMPLE_OUT") or os.path.join(os.getcwd(), "python-example")
    example = os.path.join(HERE, "..", "examples", "fit_sphere.py")
    subprocess.run([sys.executable, example, CLOUD, "--offset", "0.05", "-o", out], check=True)
    for name, radius in (("zero", 0.5), ("offset", 0.45)):
        vertices, faces = duplexfit.read_mesh(os.path.join(out, name + ".ply"))
        r = np.linalg.norm(vertices, axis=1)  # sphere_10k is centred at the origin
        error = np.abs(r - radius).max()
        topology = duplexfit.mesh_topology(vertices, faces)
        print(f"{name}.ply: {len(faces)} triangles, max |r - {radius}| = {error:.2e}, "
              f"watertight {topology['watertight']}, components {topology['components']}")
        assert len(faces) > 10000, len(faces)
        assert error < 1e-3, error
        assert topology["watertight"] and topology["components"] == 1, topology
    field = duplexfit.load_field(os.path.join(out, "field.dpxf"))
    assert field.offsets == [0.05], field.offsets
    print("OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
