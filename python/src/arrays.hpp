// numpy ⇄ Eigen for the Python module: (N, 3) arrays of points, normals, vertices and faces. Inputs are
// anything numpy.asarray accepts (lists, non-contiguous views, integer or float dtypes); they are copied
// into the library's row-major matrices. A wrong shape or dtype is a ValueError naming the argument.
#pragma once

#include <cstdint>
#include <cstring>
#include <sstream>
#include <string>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "duplexfit/mesh.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::python {

namespace py = pybind11;

/// "(5, 2)" for an array of shape (5, 2).
inline std::string shapeText(const py::array& a) {
  std::ostringstream s;
  s << "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s << (d ? ", " : "") << a.shape(d);
  s << (a.ndim() == 1 ? ",)" : ")");
  return s.str();
}

/// `obj` as a numpy array of shape (N, 3) whose dtype kind is one of `kinds` ("fiu": numbers, "iu":
/// integers). @throws py::value_error naming `name` otherwise.
inline py::array checkedRows3(const py::handle& obj, const char* name, const char* kinds, const char* what) {
  py::array a = py::array::ensure(obj);
  if (!a) throw py::value_error(std::string(name) + " must be an (N, 3) array of " + what);
  // dtype.kind through Python: pybind11's inlined dtype::kind() trips GCC's -Wnull-dereference.
  const py::object dtype = a.attr("dtype");
  const std::string kind = dtype.attr("kind").cast<std::string>();
  if (kind.size() != 1 || std::strchr(kinds, kind[0]) == nullptr) {
    throw py::value_error(std::string(name) + " must be an (N, 3) array of " + what + "; got dtype " +
                          py::str(dtype).cast<std::string>());
  }
  if (a.ndim() != 2 || a.shape(1) != 3) {
    throw py::value_error(std::string(name) + " must have shape (N, 3); got shape " + shapeText(a));
  }
  return a;
}

/// An (N, 3) array of numbers as Points (a copy, converted to float64).
inline Points toPoints(const py::handle& obj, const char* name) {
  const py::array checked = checkedRows3(obj, name, "fiu", "numbers");
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(checked);
  if (!a) throw py::value_error(std::string(name) + " cannot be converted to float64");
  Points p(a.shape(0), 3);
  if (a.size() > 0) std::memcpy(p.data(), a.data(), sizeof(double) * static_cast<std::size_t>(a.size()));
  return p;
}

/// An (F, 3) array of integer vertex indices as Faces. @throws py::value_error for a negative index or one
/// above 2^31 − 1 (naming the face); indices past the vertices are left to the library (it names the face).
inline Faces toFaces(const py::handle& obj, const char* name) {
  const py::array checked = checkedRows3(obj, name, "iu", "integer vertex indices");
  const auto a = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(checked);
  if (!a) throw py::value_error(std::string(name) + " cannot be converted to int64");
  Faces f(a.shape(0), 3);
  const std::int64_t* v = a.data();
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    if (v[i] < 0 || v[i] > INT32_MAX) {
      throw py::value_error(std::string(name) + ": face " + std::to_string(i / 3) + " has the vertex index " +
                            std::to_string(v[i]) + " (indices must be in [0, 2^31 - 1])");
    }
    f.data()[i] = static_cast<std::int32_t>(v[i]);
  }
  return f;
}

/// Points as a new (N, 3) float64 array.
inline py::array_t<double> fromPoints(const Points& p) {
  py::array_t<double> a({static_cast<py::ssize_t>(p.rows()), py::ssize_t{3}});
  if (p.size() > 0) std::memcpy(a.mutable_data(), p.data(), sizeof(double) * static_cast<std::size_t>(p.size()));
  return a;
}

/// Faces as a new (F, 3) int32 array.
inline py::array_t<std::int32_t> fromFaces(const Faces& f) {
  py::array_t<std::int32_t> a({static_cast<py::ssize_t>(f.rows()), py::ssize_t{3}});
  if (f.size() > 0) {
    std::memcpy(a.mutable_data(), f.data(), sizeof(std::int32_t) * static_cast<std::size_t>(f.size()));
  }
  return a;
}

/// A vector as a new (N,) float64 array.
inline py::array_t<double> fromVector(const Eigen::VectorXd& v) {
  py::array_t<double> a(static_cast<py::ssize_t>(v.size()));
  if (v.size() > 0) std::memcpy(a.mutable_data(), v.data(), sizeof(double) * static_cast<std::size_t>(v.size()));
  return a;
}

/// A 3-vector as a new (3,) float64 array.
inline py::array_t<double> fromVector3(const Eigen::Vector3d& v) {
  py::array_t<double> a(3);
  std::memcpy(a.mutable_data(), v.data(), sizeof(double) * 3);
  return a;
}

/// (vertices, faces) of a mesh.
inline py::tuple fromMesh(const Mesh& m) { return py::make_tuple(fromPoints(m.vertices), fromFaces(m.faces)); }

/// A mesh from two arrays (copies).
inline Mesh toMesh(const py::handle& vertices, const py::handle& faces) {
  Mesh m;
  m.vertices = toPoints(vertices, "vertices");
  m.faces = toFaces(faces, "faces");
  return m;
}

}  // namespace duplexfit::python
