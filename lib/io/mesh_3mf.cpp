// 3MF (3D Manufacturing Format) meshes through lib3mf, the 3MF Consortium's reference implementation
// (Debian: lib3mf-dev, optional at build time): one mesh object, one build item, unit millimetre, written
// to memory and committed atomically. The UUIDs the production extension asks for are derived from the
// mesh's content, so that writing the same mesh twice gives the same bytes.
#include "io/mesh_3mf.hpp"

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/error.hpp"

#ifdef DUPLEXFIT_HAVE_LIB3MF
#include <Model/COM/NMR_DLLInterfaces.h>
#endif

namespace duplexfit::io {

bool threeMfAvailable() noexcept {
#ifdef DUPLEXFIT_HAVE_LIB3MF
  return true;
#else
  return false;
#endif
}

#ifndef DUPLEXFIT_HAVE_LIB3MF

void write3mf(const std::string& path, const Mesh& /*mesh*/) {
  throw InvalidArgument(path + ": this build of duplexfit has no lib3mf (Debian: lib3mf-dev), so it cannot write "
                               "3MF; write .ply, .obj or .stl, or rebuild with lib3mf-dev installed");
}

Mesh read3mf(const std::string& path) {
  throw InvalidArgument(path + ": this build of duplexfit has no lib3mf (Debian: lib3mf-dev), so it cannot read 3MF");
}

#else

namespace {

/// Releases a lib3mf handle at scope exit.
struct Handle {
  NMR::PLib3MFBase* p = nullptr;
  Handle() = default;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() {
    if (p != nullptr) NMR::lib3mf_release(p);
  }
  template <class T>
  T** out() {
    return reinterpret_cast<T**>(&p);
  }
};

/// Throws IoError naming the file, the step and lib3mf's own message when `result` is not LIB3MF_OK.
void check(LIB3MFRESULT result, NMR::PLib3MFBase* on, const std::string& path, const char* step) {
  if (result == LIB3MF_OK) return;
  std::string message;
  if (on != nullptr) {
    DWORD code = 0;
    LPCSTR text = nullptr;
    if (NMR::lib3mf_getlasterror(on, &code, &text) == LIB3MF_OK && text != nullptr) message = text;
  }
  char hex[32];
  std::snprintf(hex, sizeof hex, "0x%08x", static_cast<unsigned>(result));
  throw IoError(path + ": 3MF " + step + " failed (lib3mf " + hex + (message.empty() ? "" : ": " + message) + ")");
}

/// A UUID (RFC 4122 layout, version 4 and variant bits set) from a 128-bit FNV-1a hash of the mesh and a
/// salt: deterministic for the same content.
std::string contentUuid(const Mesh& mesh, std::uint64_t salt) {
  std::uint64_t h1 = 0xcbf29ce484222325ULL ^ salt, h2 = 0x84222325cbf29ce4ULL + salt;
  const auto mix = [&](const void* data, std::size_t bytes) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) {
      h1 = (h1 ^ b[i]) * 0x100000001b3ULL;
      h2 = (h2 ^ b[i]) * 0x100000001b3ULL + (h1 >> 29);
    }
  };
  mix(mesh.vertices.data(), static_cast<std::size_t>(mesh.vertices.size()) * sizeof(double));
  mix(mesh.faces.data(), static_cast<std::size_t>(mesh.faces.size()) * sizeof(mesh.faces(0, 0)));
  char text[40];
  std::snprintf(text, sizeof text, "%08x-%04x-4%03x-%04x-%012llx", static_cast<unsigned>(h1 >> 32),
                static_cast<unsigned>((h1 >> 16) & 0xffffU), static_cast<unsigned>(h1 & 0xfffU),
                static_cast<unsigned>(0x8000U | ((h2 >> 48) & 0x3fffU)),
                static_cast<unsigned long long>(h2 & 0xffffffffffffULL));
  return text;
}

}  // namespace

void write3mf(const std::string& path, const Mesh& mesh) {
  const auto nv = static_cast<std::size_t>(mesh.vertices.rows());
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  std::vector<NMR::MODELMESHVERTEX> vertices(nv);
  for (std::size_t i = 0; i < nv; ++i) {
    for (int k = 0; k < 3; ++k) {
      vertices[i].m_fPosition[k] = static_cast<float>(mesh.vertices(static_cast<Eigen::Index>(i), k));
    }
  }
  std::vector<NMR::MODELMESHTRIANGLE> triangles(nf);
  for (std::size_t i = 0; i < nf; ++i) {
    for (int k = 0; k < 3; ++k) {
      triangles[i].m_nIndices[k] = static_cast<DWORD>(mesh.faces(static_cast<Eigen::Index>(i), k));
    }
  }
  Handle model, object, item, writer;
  check(NMR::lib3mf_createmodel(model.out<NMR::PLib3MFModel>()), nullptr, path, "model creation");
  check(NMR::lib3mf_model_setunit(model.p, NMR::MODELUNIT_MILLIMETER), model.p, path, "unit");
  check(NMR::lib3mf_model_addmeshobject(model.p, object.out<NMR::PLib3MFModelMeshObject>()), model.p, path,
        "mesh object");
  check(NMR::lib3mf_meshobject_setgeometry(object.p, vertices.data(), static_cast<DWORD>(nv), triangles.data(),
                                           static_cast<DWORD>(nf)),
        object.p, path, "geometry");
  check(NMR::lib3mf_object_setnameutf8(object.p, "duplexfit mesh"), object.p, path, "object name");
  check(NMR::lib3mf_object_setuuidutf8(object.p, contentUuid(mesh, 1).c_str()), object.p, path, "object UUID");
  check(NMR::lib3mf_model_addbuilditem(model.p, object.p, nullptr, item.out<NMR::PLib3MFModelBuildItem>()), model.p,
        path, "build item");
  check(NMR::lib3mf_builditem_setuuidutf8(item.p, contentUuid(mesh, 2).c_str()), item.p, path, "build item UUID");
  check(NMR::lib3mf_model_setbuilduuidutf8(model.p, contentUuid(mesh, 3).c_str()), model.p, path, "build UUID");
  check(NMR::lib3mf_model_querywriter(model.p, "3mf", writer.out<NMR::PLib3MFModelWriter>()), model.p, path,
        "writer");
  ULONG64 size = 0;
  check(NMR::lib3mf_writer_getstreamsize(writer.p, &size), writer.p, path, "packaging");
  std::vector<BYTE> bytes(static_cast<std::size_t>(size));
  check(NMR::lib3mf_writer_writetobuffer(writer.p, bytes.data(), size), writer.p, path, "packaging");
  AtomicFile file(path);
  file.write(bytes.data(), bytes.size());
  file.commit();
}

Mesh read3mf(const std::string& path) {
  Handle model, reader, objects;
  check(NMR::lib3mf_createmodel(model.out<NMR::PLib3MFModel>()), nullptr, path, "model creation");
  check(NMR::lib3mf_model_queryreader(model.p, "3mf", reader.out<NMR::PLib3MFModelReader>()), model.p, path, "reader");
  check(NMR::lib3mf_reader_readfromfileutf8(reader.p, path.c_str()), reader.p, path, "reading");
  check(NMR::lib3mf_model_getmeshobjects(model.p, objects.out<NMR::PLib3MFModelResourceIterator>()), model.p, path,
        "mesh objects");
  std::vector<double> positions;
  std::vector<std::int32_t> faces;
  for (;;) {
    BOOL more = 0;
    check(NMR::lib3mf_resourceiterator_movenext(objects.p, &more), objects.p, path, "mesh objects");
    if (!more) break;
    Handle object;
    check(NMR::lib3mf_resourceiterator_getcurrent(objects.p, object.out<NMR::PLib3MFModelResource>()), objects.p,
          path, "mesh objects");
    DWORD nv = 0, nf = 0;
    check(NMR::lib3mf_meshobject_getvertexcount(object.p, &nv), object.p, path, "vertices");
    check(NMR::lib3mf_meshobject_gettrianglecount(object.p, &nf), object.p, path, "triangles");
    std::vector<NMR::MODELMESHVERTEX> v(nv);
    std::vector<NMR::MODELMESHTRIANGLE> t(nf);
    if (nv > 0) check(NMR::lib3mf_meshobject_getvertices(object.p, v.data(), nv, nullptr), object.p, path, "vertices");
    if (nf > 0) {
      check(NMR::lib3mf_meshobject_gettriangleindices(object.p, t.data(), nf, nullptr), object.p, path, "triangles");
    }
    const auto base = static_cast<std::int64_t>(positions.size() / 3);
    if (base + static_cast<std::int64_t>(nv) > INT32_MAX) throw IoError(path + ": more than 2^31 vertices");
    for (const auto& x : v) positions.insert(positions.end(), {x.m_fPosition[0], x.m_fPosition[1], x.m_fPosition[2]});
    for (DWORD i = 0; i < nf; ++i) {
      for (int k = 0; k < 3; ++k) {
        if (t[i].m_nIndices[k] >= nv) {
          throw IoError(path + ": triangle " + std::to_string(i) + " has vertex index " +
                        std::to_string(t[i].m_nIndices[k]) + " of " + std::to_string(nv));
        }
        faces.push_back(static_cast<std::int32_t>(base + t[i].m_nIndices[k]));
      }
    }
  }
  Mesh mesh;
  mesh.vertices = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      positions.data(), static_cast<Eigen::Index>(positions.size() / 3), 3);
  mesh.faces = Eigen::Map<const Eigen::Matrix<std::int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      faces.data(), static_cast<Eigen::Index>(faces.size() / 3), 3);
  return mesh;
}

#endif

}  // namespace duplexfit::io
