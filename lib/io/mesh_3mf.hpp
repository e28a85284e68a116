// 3MF meshes (lib3mf, when the build has it): the part of writeMesh/readMesh for MeshFormat::ThreeMf.
#pragma once

#include <string>

#include "duplexfit/mesh.hpp"

namespace duplexfit::io {

/// True when the build has lib3mf.
bool threeMfAvailable() noexcept;
/// One mesh object and one build item, unit millimetre, float32 coordinates, written atomically.
/// @throws InvalidArgument without lib3mf in the build (saying so); IoError naming the file.
void write3mf(const std::string& path, const Mesh& mesh);
/// Every mesh object of the model, as one mesh (build-item transforms are not applied).
/// @throws InvalidArgument without lib3mf; IoError naming the file and the step or triangle.
Mesh read3mf(const std::string& path);

}  // namespace duplexfit::io
