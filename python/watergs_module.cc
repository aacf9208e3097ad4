// The extension `watergs._watergs` behind the Python module (issue 18).
// The CLI's commands run in-process through their registry entries, so that
// Python takes its options, defaults, checks and one-line errors from the
// code the CLI runs; the objects a Python pipeline handles directly (PLY
// models, COLMAP workspaces, cameras, renders) are bound as classes whose
// arrays are numpy arrays. The pure-Python layer (python/watergs/*.py) turns
// keyword arguments into the command lines and the files the commands write
// into result objects.
//
// Rules every binding here keeps: bad input raises one exception with a
// one-line message (watergs::Error becomes watergs.Error with the CLI's
// text; a wrong Python type is a TypeError) and never reaches code that
// could crash the interpreter; long work runs with the GIL released; numpy
// is imported only by the calls that take or return arrays, so that
// `import watergs` works in an interpreter without it.
#include <fcntl.h>
#include <omp.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/device.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/image.h"
#include "gaussian/rasterizer.h"
#include "gaussian/util/error.h"
#include "gaussian/util/progress.h"
#include "plugin/command.h"
#include "plugin/image_file.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"

namespace py = pybind11;

namespace watergs {
namespace {

// ---------------------------------------------------------------------------
// Conversions with one-line errors.

// The Python type's name, for TypeError messages.
std::string TypeName(py::handle value) {
  return py::str(py::type::of(value).attr("__name__"));
}

// A file path: str or os.PathLike (pathlib.Path).
std::string ToPath(py::handle value, const std::string& what) {
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::hasattr(value, "__fspath__")) {
    py::object path = value.attr("__fspath__")();
    if (py::isinstance<py::str>(path)) return path.cast<std::string>();
  }
  throw py::type_error(what + " must be a path (str or os.PathLike), not " +
                       TypeName(value));
}

// A real number (int, float, numpy scalar; not bool, not str).
double ToDouble(py::handle value, const std::string& what) {
  if (PyBool_Check(value.ptr()) || py::isinstance<py::str>(value) ||
      !PyNumber_Check(value.ptr())) {
    throw py::type_error(what + " must be a number, not " + TypeName(value));
  }
  const double x = PyFloat_AsDouble(value.ptr());
  if (x == -1.0 && PyErr_Occurred()) throw py::error_already_set();
  return x;
}

// An integer (int, numpy integer; not bool).
int64_t ToInt(py::handle value, const std::string& what) {
  if (PyBool_Check(value.ptr()) || !PyIndex_Check(value.ptr())) {
    throw py::type_error(what + " must be an integer, not " + TypeName(value));
  }
  const long long x = PyLong_AsLongLong(value.ptr());
  if (x == -1 && PyErr_Occurred()) {
    PyErr_Clear();
    Fail(what + " is out of range");
  }
  return x;
}

// `value` as a C-contiguous numpy array of T (numbers converted), with the
// given shape (-1: any extent); TypeError if it is not an array of numbers,
// Error for another shape or a NaN/Inf entry.
template <typename T>
py::array_t<T, py::array::c_style> ToArray(py::handle value,
                                           const std::vector<ssize_t>& shape,
                                           const std::string& what) {
  if (py::isinstance<py::str>(value) || py::isinstance<py::bytes>(value) ||
      value.is_none()) {
    throw py::type_error(what + " must be an array of numbers, not " +
                         TypeName(value));
  }
  auto array =
      py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(value);
  if (!array) {
    throw py::type_error(what + " must be an array of numbers, not " +
                         TypeName(value));
  }
  bool fits = array.ndim() == ssize_t(shape.size());
  for (size_t d = 0; fits && d < shape.size(); ++d) {
    fits = shape[d] < 0 || array.shape(d) == shape[d];
  }
  if (!fits) {
    std::string want, got;
    for (size_t d = 0; d < shape.size(); ++d) {
      want += (d ? ", " : "") +
              (shape[d] < 0 ? std::string("N") : std::to_string(shape[d]));
    }
    for (ssize_t d = 0; d < array.ndim(); ++d) {
      got += (d ? ", " : "") + std::to_string(array.shape(d));
    }
    Fail(what + " must have shape (" + want + "), not (" + got + ")");
  }
  const T* data = array.data();
  for (ssize_t i = 0; i < array.size(); ++i) {
    if (!std::isfinite(double(data[i]))) {
      Fail(what + " holds NaN or Inf (entry " + std::to_string(i) + ")");
    }
  }
  return array;
}

// A background colour: "black", "white", "r,g,b", or three numbers in
// [0, 1].
std::array<float, 3> ToBackground(py::handle value) {
  if (py::isinstance<py::str>(value)) {
    return ParseBackground(value.cast<std::string>());
  }
  const auto rgb = ToArray<double>(value, {3}, "background");
  std::array<float, 3> out;
  for (int c = 0; c < 3; ++c) {
    if (!(rgb.at(c) >= 0 && rgb.at(c) <= 1)) {
      Fail("background: components must be in [0, 1]");
    }
    out[c] = float(rgb.at(c));
  }
  return out;
}

// An image as a height x width x 3 numpy array (a copy).
py::array_t<float> ToNumpy(const ImageRGB& image) {
  py::array_t<float> out(
      {ssize_t(image.height), ssize_t(image.width), ssize_t(3)});
  std::copy(image.data.begin(), image.data.end(), out.mutable_data());
  return out;
}

// `count` floats as a numpy array of `shape` (a copy).
py::array_t<float> ToNumpy(const std::vector<float>& values,
                           const std::vector<ssize_t>& shape) {
  py::array_t<float> out(shape);
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

// ---------------------------------------------------------------------------
// Commands.

// One command at a time: commands set process-wide state (the OpenMP thread
// count, the stdout/stderr redirection of `quiet`).
std::mutex command_mutex;

// Sends stdout and stderr (file descriptors 1 and 2: the commands' printf,
// iostreams and progress line) to /dev/null while alive.
class Silence {
 public:
  Silence() {
    Flush();
    null_ = ::open("/dev/null", O_WRONLY);
    for (int fd : {1, 2}) {
      saved_[fd - 1] = ::dup(fd);
      if (null_ >= 0 && saved_[fd - 1] >= 0) ::dup2(null_, fd);
    }
  }
  ~Silence() {
    Flush();
    for (int fd : {1, 2}) {
      if (saved_[fd - 1] < 0) continue;
      ::dup2(saved_[fd - 1], fd);
      ::close(saved_[fd - 1]);
    }
    if (null_ >= 0) ::close(null_);
  }
  Silence(const Silence&) = delete;
  Silence& operator=(const Silence&) = delete;

  static void Flush() {
    std::cout.flush();
    std::cerr.flush();
    std::fflush(stdout);
    std::fflush(stderr);
  }

 private:
  int null_ = -1;
  int saved_[2] = {-1, -1};
};

// Restores what a command changes for the process: the OpenMP thread count
// (--num_threads) and the calling thread's progress observer.
class CommandScope {
 public:
  explicit CommandScope(ProgressObserver observer)
      : threads_(omp_get_max_threads()),
        previous_(SetProgressObserver(std::move(observer))) {}
  ~CommandScope() {
    Silence::Flush();
    omp_set_num_threads(threads_);
    SetProgressObserver(std::move(previous_));
  }
  CommandScope(const CommandScope&) = delete;
  CommandScope& operator=(const CommandScope&) = delete;

 private:
  int threads_;
  ProgressObserver previous_;
};

const Command& FindCommand(const std::string& name) {
  const auto& registry = CommandRegistry();
  const auto it = registry.find(name);
  if (it == registry.end()) Fail("unknown command `" + name + "`");
  return it->second;
}

// Runs `watergs <name> <args...>` in this process with the GIL released;
// returns its exit code. `progress(label, done, total, status, finished)`
// is called at each step of the command's progress line, with the GIL held;
// Ctrl-C (KeyboardInterrupt) and an exception raised by `progress` stop the
// command there and are raised again once it has unwound (a train run
// removes the output folder it created, as after any error).
int RunCommand(const std::string& name, const std::vector<std::string>& args,
               const py::object& progress, bool quiet) {
  const Command& command = FindCommand(name);
  std::vector<std::string> words = {name};
  words.insert(words.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& word : words) argv.push_back(word.data());
  argv.push_back(nullptr);
  const ProgressObserver observer = [&progress](const ProgressEvent& event) {
    py::gil_scoped_acquire acquire;
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    if (!progress.is_none()) {
      progress(event.label, event.done, event.total, event.status,
               event.finished);
    }
  };
  py::gil_scoped_release release;
  std::lock_guard<std::mutex> lock(command_mutex);
  CommandScope scope(observer);
  std::optional<Silence> silence;
  if (quiet) silence.emplace();
  return command.run(int(words.size()), argv.data());
}

// What `watergs <name> -h` prints: the options, their defaults and help.
std::string CommandHelp(const std::string& name) {
  const Command& command = FindCommand(name);
  std::string words[] = {name, "-h"};
  char* argv[] = {words[0].data(), words[1].data(), nullptr};
  std::ostringstream text;
  // Released before locking: a command holding the lock takes the GIL in
  // its progress observer.
  py::gil_scoped_release release;
  std::lock_guard<std::mutex> lock(command_mutex);
  std::streambuf* const saved = std::cout.rdbuf(text.rdbuf());
  try {
    command.run(2, argv);
  } catch (...) {
    std::cout.rdbuf(saved);
    throw;
  }
  std::cout.rdbuf(saved);
  return text.str();
}

// ---------------------------------------------------------------------------
// Cameras.

// Refuses a camera the rasterizer cannot render: one line naming the field.
void CheckCamera(const RenderCamera& c) {
  if (c.width < 1 || c.height < 1 || c.width > 16384 || c.height > 16384) {
    Fail("Camera: width and height must be 1-16384 pixels, not " +
         std::to_string(c.width) + "x" + std::to_string(c.height));
  }
  const double values[] = {c.fx, c.fy, c.cx, c.cy};
  const char* names[] = {"fx", "fy", "cx", "cy"};
  for (int k = 0; k < 4; ++k) {
    if (!std::isfinite(values[k])) {
      Fail(std::string("Camera: ") + names[k] + " is NaN or Inf");
    }
  }
  if (!(c.fx > 0 && c.fy > 0)) Fail("Camera: fx and fy must be > 0");
  if (!c.R.allFinite() || !c.t.allFinite()) {
    Fail("Camera: R and t must not hold NaN or Inf");
  }
  const double orthogonality =
      (c.R.transpose() * c.R - Eigen::Matrix3d::Identity())
          .cwiseAbs()
          .maxCoeff();
  if (orthogonality > 1e-4 || c.R.determinant() < 0) {
    Fail(
        "Camera: R is not a rotation matrix (orthonormal, determinant +1); "
        "it maps world to camera coordinates, X_cam = R X_world + t");
  }
}

RenderCamera MakeCamera(py::handle width, py::handle height, py::handle fx,
                        py::handle fy, py::handle cx, py::handle cy,
                        py::handle rotation, py::handle translation) {
  RenderCamera c;
  const int64_t w = ToInt(width, "Camera: width");
  const int64_t h = ToInt(height, "Camera: height");
  if (w < 1 || h < 1 || w > 16384 || h > 16384) {
    Fail("Camera: width and height must be 1-16384 pixels, not " +
         std::to_string(w) + "x" + std::to_string(h));
  }
  c.width = int(w);
  c.height = int(h);
  c.fx = ToDouble(fx, "Camera: fx");
  c.fy = ToDouble(fy, "Camera: fy");
  c.cx = cx.is_none() ? 0.5 * c.width : ToDouble(cx, "Camera: cx");
  c.cy = cy.is_none() ? 0.5 * c.height : ToDouble(cy, "Camera: cy");
  if (!rotation.is_none()) {
    const auto r = ToArray<double>(rotation, {3, 3}, "Camera: R");
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) c.R(i, j) = r.at(i, j);
    }
  }
  if (!translation.is_none()) {
    const auto t = ToArray<double>(translation, {3}, "Camera: t");
    for (int i = 0; i < 3; ++i) c.t(i) = t.at(i);
  }
  CheckCamera(c);
  return c;
}

py::array_t<double> ToNumpy(const Eigen::Matrix3d& m) {
  py::array_t<double> out({ssize_t(3), ssize_t(3)});
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) out.mutable_at(i, j) = m(i, j);
  }
  return out;
}

py::array_t<double> ToNumpy(const Eigen::Vector3d& v) {
  py::array_t<double> out(ssize_t(3));
  for (int i = 0; i < 3; ++i) out.mutable_at(i) = v(i);
  return out;
}

// ---------------------------------------------------------------------------
// Models.

// A 3DGS model and the PLY layout it is written back in (extras such as
// normals kept, as the CLI keeps them).
struct Model {
  GaussianModel model;
  PlyLayout layout;
  // The file it was read from; empty for one made from arrays.
  std::string path;
};

Model LoadModel(const std::string& path) {
  PlyData ply;
  {
    py::gil_scoped_release release;
    ply = ReadModelFile(path);
  }
  return Model{std::move(ply.model), std::move(ply.layout), path};
}

// Inria's in-memory arrays (gsplat's means, scales, quats, opacities, sh0,
// shN after log/logit as Inria stores them) as a model.
Model ModelFromArrays(py::handle means, py::handle log_scales, py::handle quats,
                      py::handle opacity_logits, py::handle sh_dc,
                      py::handle sh_rest) {
  const auto xyz = ToArray<float>(means, {-1, 3}, "means");
  const ssize_t n = xyz.shape(0);
  const auto scales = ToArray<float>(log_scales, {n, 3}, "log_scales");
  const auto rotations = ToArray<float>(quats, {n, 4}, "quats");
  const auto opacity =
      ToArray<float>(opacity_logits, {n}, "opacity_logits (shape (N,))");
  const auto dc = ToArray<float>(sh_dc, {n, 3}, "sh_dc");
  Model m;
  int coefficients = 0;
  std::optional<py::array_t<float, py::array::c_style>> rest;
  if (!sh_rest.is_none()) {
    rest = ToArray<float>(sh_rest, {n, -1, 3}, "sh_rest");
    coefficients = int(rest->shape(1));
  }
  const int degrees[] = {0, 3, 8, 15};
  const int* degree = std::find(degrees, degrees + 4, coefficients);
  if (degree == degrees + 4) {
    Fail(
        "sh_rest must hold 0, 3, 8 or 15 coefficients per Gaussian (SH "
        "degree 0-3), not " +
        std::to_string(coefficients));
  }
  m.model.sh_degree = int(degree - degrees);
  m.model.Resize(size_t(n));
  std::copy_n(xyz.data(), 3 * n, m.model.means.begin());
  std::copy_n(scales.data(), 3 * n, m.model.log_scales.begin());
  std::copy_n(rotations.data(), 4 * n, m.model.quats.begin());
  std::copy_n(opacity.data(), n, m.model.opacity_logits.begin());
  std::copy_n(dc.data(), 3 * n, m.model.sh_dc.begin());
  if (rest) std::copy_n(rest->data(), rest->size(), m.model.sh_rest.begin());
  for (ssize_t i = 0; i < n; ++i) {
    const float* q = &m.model.quats[4 * i];
    if (q[0] == 0 && q[1] == 0 && q[2] == 0 && q[3] == 0) {
      Fail("quats: Gaussian " + std::to_string(i) +
           " has a zero quaternion (no rotation)");
    }
  }
  m.layout = InriaPlyLayout(m.model.sh_degree, size_t(n));
  return m;
}

py::array_t<float> Render(const Model& m, const RenderCamera& camera,
                          py::handle background, py::handle sh_degree,
                          const std::string& device) {
  RenderOptions options;
  options.background = ToBackground(background);
  options.active_sh_degree = int(ToInt(sh_degree, "sh_degree"));
  if (options.active_sh_degree < -1 ||
      options.active_sh_degree > m.model.sh_degree) {
    Fail("sh_degree " + std::to_string(options.active_sh_degree) +
         " is not in -1.." + std::to_string(m.model.sh_degree) +
         " for this model");
  }
  CheckCamera(camera);
  const Device resolved = ResolveDevice(device);
  ImageRGB image;
  {
    py::gil_scoped_release release;
    MakeRasterizer(resolved)->Forward(m.model, camera, options, &image,
                                      nullptr);
    // As `watergs render` writes it.
    for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
  }
  return ToNumpy(image);
}

// ---------------------------------------------------------------------------
// Workspaces.

// An open COLMAP workspace and its views (which refer to it).
struct WorkspaceHandle {
  std::unique_ptr<Workspace> workspace;
  std::unique_ptr<WorkspaceViews> views;

  size_t Index(py::handle view) const {
    int64_t i = ToInt(view, "view");
    const int64_t n = int64_t(workspace->NumViews());
    if (i < 0) i += n;
    if (i < 0 || i >= n) {
      throw py::index_error("view " + std::to_string(ToInt(view, "view")) +
                            " is not in 0.." + std::to_string(n - 1));
    }
    return size_t(i);
  }
};

std::shared_ptr<WorkspaceHandle> OpenWorkspace(py::handle path,
                                               py::handle downscale,
                                               py::handle sparse_path,
                                               py::handle image_path) {
  WorkspaceOptions options;
  options.workspace_path = ToPath(path, "workspace_path");
  options.downscale = int(ToInt(downscale, "downscale"));
  if (!sparse_path.is_none()) {
    options.input_path = ToPath(sparse_path, "sparse_path");
  }
  if (!image_path.is_none()) {
    options.image_path = ToPath(image_path, "image_path");
  }
  const int d = options.downscale;
  if (d != 1 && d != 2 && d != 4 && d != 8) {
    Fail("downscale must be 1, 2, 4 or 8");
  }
  // Cameras are usable without the images; image() then says so.
  options.images_optional = true;
  auto handle = std::make_shared<WorkspaceHandle>();
  {
    py::gil_scoped_release release;
    handle->workspace =
        std::make_unique<Workspace>(Workspace::Open(std::move(options)));
  }
  handle->views = std::make_unique<WorkspaceViews>(*handle->workspace);
  return handle;
}

}  // namespace
}  // namespace watergs

PYBIND11_MODULE(_watergs, m) {
  using namespace watergs;
  m.doc() =
      "watergs' C++ core: the CLI commands run in-process, models, "
      "workspaces, cameras. Use the `watergs` package, not this module.";
  m.attr("__version__") = Version();
  // The git commit the module was built from ("unknown" outside a checkout).
  m.attr("__commit__") = GitCommit();
  py::register_exception<Error>(m, "Error", PyExc_RuntimeError);

  m.def("run_command", &RunCommand, py::arg("name"), py::arg("args"),
        py::arg("progress") = py::none(), py::arg("quiet") = false);
  m.def("command_help", &CommandHelp, py::arg("name"));
  m.def("command_names", [] {
    std::vector<std::string> names;
    for (const auto& [name, command] : CommandRegistry()) {
      names.push_back(name);
    }
    return names;
  });
  m.def("cuda_available", [] {
    std::string why;
    const bool available = CudaAvailable(&why);
    return std::make_pair(available, why);
  });
  m.def(
      "read_image_u8",
      [](py::handle path_object) {
        const std::string path = ToPath(path_object, "path");
        cv::Mat rgb;
        {
          py::gil_scoped_release release;
          rgb = DecodeImageFile(path);
        }
        py::array_t<uint8_t> out(
            {ssize_t(rgb.rows), ssize_t(rgb.cols), ssize_t(3)});
        uint8_t* data = out.mutable_data();
        for (int y = 0; y < rgb.rows; ++y) {
          const float* row = rgb.ptr<float>(y);
          for (int k = 0; k < 3 * rgb.cols; ++k) {
            *data++ = uint8_t(std::lround(std::clamp(row[k], 0.f, 1.f) * 255));
          }
        }
        return out;
      },
      py::arg("path"));

  py::class_<RenderCamera>(m, "Camera",
                           "A pinhole camera: image size, intrinsics in "
                           "pixels and the world-to-camera pose X_cam = R "
                           "X_world + t (COLMAP's convention: +z forward, +y "
                           "down).")
      .def(py::init(&MakeCamera), py::arg("width"), py::arg("height"),
           py::arg("fx"), py::arg("fy"), py::arg("cx") = py::none(),
           py::arg("cy") = py::none(), py::arg("R") = py::none(),
           py::arg("t") = py::none(),
           "cx, cy default to the image centre, R to the identity, t to "
           "zero. NaN/Inf, a non-rotation R or a bad size raise "
           "watergs.Error.")
      .def_readonly("width", &RenderCamera::width)
      .def_readonly("height", &RenderCamera::height)
      .def_readonly("fx", &RenderCamera::fx)
      .def_readonly("fy", &RenderCamera::fy)
      .def_readonly("cx", &RenderCamera::cx)
      .def_readonly("cy", &RenderCamera::cy)
      .def_property_readonly(
          "R", [](const RenderCamera& c) { return ToNumpy(c.R); },
          "World-to-camera rotation, 3x3")
      .def_property_readonly(
          "t", [](const RenderCamera& c) { return ToNumpy(c.t); },
          "World-to-camera translation, 3")
      .def_property_readonly(
          "center",
          [](const RenderCamera& c) {
            return ToNumpy(Eigen::Vector3d(c.Center()));
          },
          "Camera centre in world coordinates, -R^T t")
      .def("__repr__", [](const RenderCamera& c) {
        std::ostringstream out;
        out << "watergs.Camera(" << c.width << "x" << c.height
            << ", fx=" << c.fx << ", fy=" << c.fy << ")";
        return out.str();
      });

  py::class_<Model>(m, "Model",
                    "A 3D Gaussian Splatting model (Inria's PLY layout). "
                    "Arrays are numpy copies.")
      .def_static(
          "load",
          [](py::handle path) { return LoadModel(ToPath(path, "path")); },
          py::arg("path"),
          "Reads a 3DGS PLY (binary or ASCII); a missing, truncated or "
          "malformed file, or NaN/Inf values, raise watergs.Error.")
      .def_static("from_arrays", &ModelFromArrays, py::arg("means"),
                  py::arg("log_scales"), py::arg("quats"),
                  py::arg("opacity_logits"), py::arg("sh_dc"),
                  py::arg("sh_rest") = py::none(),
                  "A model from Inria's parameter arrays: means (N,3), "
                  "log_scales (N,3), quats (N,4, w first), opacity_logits "
                  "(N,), sh_dc (N,3), sh_rest (N,K,3) with K = 0, 3, 8 or 15 "
                  "(None: SH degree 0). NaN/Inf or wrong shapes raise "
                  "watergs.Error.")
      .def(
          "save",
          [](const Model& self, py::handle path_object) {
            const std::string path = ToPath(path_object, "path");
            py::gil_scoped_release release;
            WritePly(path, self.model, self.layout);
          },
          py::arg("path"),
          "Writes the model as a PLY in the layout it was read with, "
          "atomically.")
      .def("render", &Render, py::arg("camera"),
           py::arg("background") = py::make_tuple(0, 0, 0),
           py::arg("sh_degree") = -1, py::arg("device") = "cpu",
           "Renders from `camera`: float32 array height x width x 3 in [0, "
           "1]. background: (r, g, b), 'black' or 'white'; sh_degree -1: the "
           "model's; device: cpu, cuda or auto.")
      .def("__len__", [](const Model& self) { return self.model.size(); })
      .def_property_readonly(
          "sh_degree", [](const Model& self) { return self.model.sh_degree; })
      .def_property_readonly("path",
                             [](const Model& self) -> py::object {
                               if (self.path.empty()) return py::none();
                               return py::str(self.path);
                             })
      .def_property_readonly(
          "means",
          [](const Model& self) {
            return ToNumpy(self.model.means, {ssize_t(self.model.size()), 3});
          })
      .def_property_readonly("log_scales",
                             [](const Model& self) {
                               return ToNumpy(self.model.log_scales,
                                              {ssize_t(self.model.size()), 3});
                             })
      .def_property_readonly(
          "quats",
          [](const Model& self) {
            return ToNumpy(self.model.quats, {ssize_t(self.model.size()), 4});
          })
      .def_property_readonly("opacity_logits",
                             [](const Model& self) {
                               return ToNumpy(self.model.opacity_logits,
                                              {ssize_t(self.model.size())});
                             })
      .def_property_readonly(
          "sh_dc",
          [](const Model& self) {
            return ToNumpy(self.model.sh_dc, {ssize_t(self.model.size()), 3});
          })
      .def_property_readonly(
          "sh_rest",
          [](const Model& self) {
            return ToNumpy(self.model.sh_rest,
                           {ssize_t(self.model.size()),
                            ssize_t(NumShCoeffs(self.model.sh_degree) - 1), 3});
          })
      .def("__repr__", [](const Model& self) {
        return "watergs.Model(" + std::to_string(self.model.size()) +
               " Gaussians, SH degree " + std::to_string(self.model.sh_degree) +
               (self.path.empty() ? "" : ", from " + self.path) + ")";
      });

  py::class_<WorkspaceHandle, std::shared_ptr<WorkspaceHandle>>(
      m, "Workspace",
      "A COLMAP workspace (images/ and sparse/0): its registered views "
      "sorted by name, their pinhole cameras (undistorted, downscaled) and "
      "images.")
      .def(py::init(&OpenWorkspace), py::arg("workspace_path"),
           py::arg("downscale") = 1, py::arg("sparse_path") = py::none(),
           py::arg("image_path") = py::none(),
           "Opens the workspace as the CLI's --workspace_path, "
           "--downscale, --sparse_path and --image_path do; bad input raises "
           "watergs.Error.")
      .def("__len__",
           [](const WorkspaceHandle& self) {
             return self.workspace->NumViews();
           })
      .def_property_readonly("names",
                             [](const WorkspaceHandle& self) {
                               std::vector<std::string> names;
                               for (size_t v = 0; v < self.views->NumViews();
                                    ++v) {
                                 names.push_back(self.views->Name(v));
                               }
                               return names;
                             })
      .def(
          "camera",
          [](const WorkspaceHandle& self, py::handle view) {
            return self.views->Camera(self.Index(view));
          },
          py::arg("view"), "The render camera of view `view` (an index).")
      .def(
          "image",
          [](const WorkspaceHandle& self, py::handle view) {
            const size_t index = self.Index(view);
            if (!self.workspace->has_images()) {
              FailAt(self.workspace->options().image_path,
                     "image folder not found");
            }
            std::shared_ptr<const ImageRGB> image;
            {
              py::gil_scoped_release release;
              image = self.views->Image(index);
            }
            return ToNumpy(*image);
          },
          py::arg("view"),
          "The view's image, float32 height x width x 3 in [0, 1].")
      .def(
          "train_views",
          [](const WorkspaceHandle& self, bool eval) {
            return self.workspace->TrainViews(eval);
          },
          py::arg("eval") = true,
          "Training views: all but every 8th with eval (LLFF convention).")
      .def(
          "test_views",
          [](const WorkspaceHandle& self, bool eval) {
            return self.workspace->TestViews(eval);
          },
          py::arg("eval") = true, "Held-out views: every 8th with eval.")
      .def_property_readonly("scene_extent",
                             [](const WorkspaceHandle& self) {
                               return self.workspace->SceneExtent();
                             })
      .def_property_readonly("has_images",
                             [](const WorkspaceHandle& self) {
                               return self.workspace->has_images();
                             })
      .def("__repr__", [](const WorkspaceHandle& self) {
        return "watergs.Workspace(" + self.workspace->options().workspace_path +
               ", " + std::to_string(self.workspace->NumViews()) + " views)";
      });
}
