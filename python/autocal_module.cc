// The Python module `autocal` (docs/python.md): datasets and results in and out as numpy
// arrays, calibration and online estimation with progress callbacks, IMU preintegration,
// registration and evaluation. A thin layer: every computation is the C++ library's.

#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl_bind.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <type_traits>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/evaluation/calibration_errors.h"
#include "autocal/evaluation/trajectory_errors.h"
#include "autocal/io/calibration_export.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/lidar/registration.h"
#include "autocal/pipeline/fleet_report.h"
#include "autocal/pipeline/multi_log_calibration.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/pipeline/online_estimation.h"
#include "autocal/sensors/imu_preintegration.h"

namespace py = pybind11;

// CalibrationFile's solver and residual maps are bound as Python objects over the C++ maps
// (not converted to dict copies), so that f.solver["k"] = "v" changes the file's map.
using SolverSummary = std::map<std::string, std::string>;
using ResidualStatistics = std::map<std::string, double>;
using Residuals = std::map<std::string, ResidualStatistics>;
PYBIND11_MAKE_OPAQUE(SolverSummary)
PYBIND11_MAKE_OPAQUE(ResidualStatistics)
PYBIND11_MAKE_OPAQUE(Residuals)

namespace autocal {
namespace python {
namespace {

using RowsX3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using RowsX4 = Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>;
using Stamps = Eigen::Matrix<int64_t, Eigen::Dynamic, 1>;

// ---- Arrays in, checked as the dataset readers check the files ----

// As the dataset readers: a stamp within 2^62 ns (146 years) of 1970, so that differences
// of stamps stay in int64.
constexpr int64_t kMaxStampNs = int64_t{1} << 62;

std::string Named(const std::string& name, const std::string& message) {
  return name + ": " + message;
}

// np.asarray(object): a list becomes an array of its natural dtype.
py::array AsArray(py::handle object, const std::string& name) {
  py::array array = py::array::ensure(object);
  if (!array) {
    throw py::type_error(
        Named(name, "expected an array, got " + std::string(py::str(py::type::of(object)))));
  }
  return array;
}

std::string DtypeOf(const py::array& array) { return py::str(array.dtype()); }

std::string ShapeOf(const py::array& array) {
  std::string shape;
  for (py::ssize_t d = 0; d < array.ndim(); ++d) {
    shape += (d > 0 ? ", " : "") + std::to_string(array.shape(d));
  }
  return "(" + shape + (array.ndim() == 1 ? ",)" : ")");
}

// Copies integer stamps of any integer dtype; every value must be within kMaxStampNs.
template <typename Integer>
Stamps CopyStamps(const py::array& array, const std::string& name) {
  const auto values =
      py::array_t<Integer, py::array::forcecast>::ensure(array).template unchecked<1>();
  Stamps t(values.shape(0));
  for (py::ssize_t k = 0; k < values.shape(0); ++k) {
    const Integer value = values(k);
    const bool negative = std::is_signed_v<Integer> && value < 0;
    const uint64_t magnitude =
        negative ? 0 - static_cast<uint64_t>(value) : static_cast<uint64_t>(value);
    if (magnitude > static_cast<uint64_t>(kMaxStampNs)) {
      throw Error(Named(name, "stamp " + std::to_string(k) + " is " + std::to_string(value) +
                                  " ns, more than 146 years from 1970 (2^62 ns): not a time in "
                                  "nanoseconds"));
    }
    t(k) = static_cast<int64_t>(value);
  }
  return t;
}

// Stamps in int64 nanoseconds: a 1-D array of an integer dtype (the values kept exactly),
// strictly increasing as every stream of a dataset. Float, complex and bool arrays are refused
// rather than rounded (an empty float array, what np.asarray([]) gives, is no stamps).
Stamps ToStamps(py::handle object, const std::string& name) {
  const py::array array = AsArray(object, name);
  if (array.ndim() != 1) {
    throw Error(Named(name, "expected a 1-D array of stamps, got shape " + ShapeOf(array)));
  }
  const char kind = array.dtype().kind();
  if (array.size() == 0 && kind == 'f') return Stamps(0);
  if (kind != 'i' && kind != 'u') {
    throw py::type_error(
        Named(name, "expected integer nanoseconds (an int64 array), got dtype " + DtypeOf(array)));
  }
  const Stamps t =
      kind == 'u' ? CopyStamps<uint64_t>(array, name) : CopyStamps<int64_t>(array, name);
  for (Eigen::Index k = 1; k < t.size(); ++k) {
    if (t(k) <= t(k - 1)) {
      throw Error(Named(name, "stamp " + std::to_string(k) + " (" + std::to_string(t(k)) +
                                  " ns) is not after stamp " + std::to_string(k - 1) + " (" +
                                  std::to_string(t(k - 1)) +
                                  " ns): stamps must strictly increase"));
    }
  }
  return t;
}

// Real numbers, finite as the dataset readers require: a float or integer array of shape
// (N, Cols) (an empty 1-D array is no rows). Complex, bool and non-numeric arrays are refused
// rather than cast.
template <int Cols>
Eigen::Matrix<double, Eigen::Dynamic, Cols, Eigen::RowMajor> ToRows(py::handle object,
                                                                    const std::string& name) {
  const py::array array = AsArray(object, name);
  const char kind = array.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw py::type_error(
        Named(name, "expected real numbers (a float array), got dtype " + DtypeOf(array)));
  }
  Eigen::Matrix<double, Eigen::Dynamic, Cols, Eigen::RowMajor> out(0, Cols);
  if (array.ndim() == 1 && array.size() == 0) return out;
  if (array.ndim() != 2 || array.shape(1) != Cols) {
    throw Error(Named(
        name, "expected an (N, " + std::to_string(Cols) + ") array, got shape " + ShapeOf(array)));
  }
  const auto values =
      py::array_t<double, py::array::forcecast>::ensure(array).template unchecked<2>();
  out.resize(values.shape(0), Cols);
  for (py::ssize_t i = 0; i < values.shape(0); ++i) {
    for (py::ssize_t j = 0; j < Cols; ++j) {
      if (!std::isfinite(values(i, j))) {
        throw Error(Named(name, "row " + std::to_string(i) + " has a non-finite value (" +
                                    std::to_string(values(i, j)) + ")"));
      }
      out(i, j) = values(i, j);
    }
  }
  return out;
}

// A vector of N real numbers (shape (N,)), checked as ToRows checks rows.
template <int N>
Eigen::Matrix<double, N, 1> ToVector(py::handle object, const std::string& name) {
  py::array array = AsArray(object, name);
  if (array.ndim() != 1 || array.shape(0) != N) {
    throw Error(Named(name, "expected an array of shape (" + std::to_string(N) + ",), got shape " +
                                ShapeOf(array)));
  }
  return ToRows<N>(array.reshape({py::ssize_t{1}, py::ssize_t{N}}), name).row(0).transpose();
}

// ---- Arrays <-> measurements ----

void RequireRows(const std::string& what, Eigen::Index rows, Eigen::Index expected) {
  if (rows != expected) {
    throw Error(what + ": " + std::to_string(rows) + " rows for " + std::to_string(expected) +
                " stamps");
  }
}

sensors::ImuSamples ImuFromArrays(py::handle t_ns_array, py::handle gyro_array,
                                  py::handle accel_array) {
  const Stamps t_ns = ToStamps(t_ns_array, "t_ns");
  const RowsX3 gyro = ToRows<3>(gyro_array, "gyro_rad_s");
  const RowsX3 accel = ToRows<3>(accel_array, "accel_m_s2");
  RequireRows("gyro_rad_s", gyro.rows(), t_ns.size());
  RequireRows("accel_m_s2", accel.rows(), t_ns.size());
  sensors::ImuSamples imu(static_cast<size_t>(t_ns.size()));
  for (Eigen::Index k = 0; k < t_ns.size(); ++k) {
    imu[k].t_ns = t_ns(k);
    imu[k].gyro_rad_s = gyro.row(k).transpose();
    imu[k].accel_m_s2 = accel.row(k).transpose();
  }
  return imu;
}

// GNSS fixes, refused where gnss.csv's reader refuses them: latitude beyond ±90°, longitude
// beyond ±180°, a standard deviation not positive.
sensors::GnssFixes GnssFromArrays(py::handle t_ns_array, py::handle lat_lon_alt_array,
                                  py::handle std_enu_array) {
  const Stamps t_ns = ToStamps(t_ns_array, "t_ns");
  const RowsX3 lat_lon_alt = ToRows<3>(lat_lon_alt_array, "lat_lon_alt");
  const RowsX3 std_enu = ToRows<3>(std_enu_array, "std_enu_m");
  RequireRows("lat_lon_alt", lat_lon_alt.rows(), t_ns.size());
  RequireRows("std_enu_m", std_enu.rows(), t_ns.size());
  sensors::GnssFixes fixes(static_cast<size_t>(t_ns.size()));
  for (Eigen::Index k = 0; k < t_ns.size(); ++k) {
    const std::string row = "row " + std::to_string(k) + ": ";
    if (std::abs(lat_lon_alt(k, 0)) > 90.0 || std::abs(lat_lon_alt(k, 1)) > 180.0) {
      throw Error(Named("lat_lon_alt", row +
                                           "latitude must be within [-90, 90] deg and longitude "
                                           "within [-180, 180] deg, got " +
                                           std::to_string(lat_lon_alt(k, 0)) + ", " +
                                           std::to_string(lat_lon_alt(k, 1))));
    }
    if (!(std_enu.row(k).minCoeff() > 0.0)) {
      throw Error(Named("std_enu_m", row + "a standard deviation must be > 0, got " +
                                         std::to_string(std_enu.row(k).minCoeff())));
    }
    fixes[k] = {t_ns(k), lat_lon_alt(k, 0), lat_lon_alt(k, 1), lat_lon_alt(k, 2),
                std_enu.row(k).transpose()};
  }
  return fixes;
}

template <typename Samples, typename Get>
Stamps StampsOf(const Samples& samples, Get get) {
  Stamps t(static_cast<Eigen::Index>(samples.size()));
  for (size_t k = 0; k < samples.size(); ++k) t(static_cast<Eigen::Index>(k)) = get(samples[k]);
  return t;
}

template <int Cols, typename Samples, typename Row>
Eigen::Matrix<double, Eigen::Dynamic, Cols, Eigen::RowMajor> RowsOf(const Samples& samples,
                                                                    Row row) {
  Eigen::Matrix<double, Eigen::Dynamic, Cols, Eigen::RowMajor> out(
      static_cast<Eigen::Index>(samples.size()), Cols);
  for (size_t k = 0; k < samples.size(); ++k)
    out.row(static_cast<Eigen::Index>(k)) = row(samples[k]);
  return out;
}

// A trajectory as (t_ns, positions (N,3), quaternions xyzw (N,4)).
py::dict TrajectoryDict(const io::Trajectory& trajectory) {
  py::dict d;
  d["t_ns"] = StampsOf(trajectory, [](const io::TrajectorySample& s) { return s.t_ns; });
  d["p_W_I"] =
      RowsOf<3>(trajectory, [](const io::TrajectorySample& s) { return s.T_W_I.p.transpose(); });
  d["q_W_I_xyzw"] = RowsOf<4>(
      trajectory, [](const io::TrajectorySample& s) { return s.T_W_I.q.coeffs().transpose(); });
  return d;
}

// A rotation from [x, y, z, w], normalized; a norm outside (0.5, 1.5) (zero, NaN, a matrix
// row or degrees by mistake) is no rotation and is refused, `what` naming it.
Eigen::Quaterniond FromXyzw(const Eigen::Vector4d& v, const std::string& what) {
  const Eigen::Quaterniond q(v(3), v(0), v(1), v(2));
  if (!(q.norm() > 0.5 && q.norm() < 1.5)) {
    throw Error(what +
                ": expected a quaternion [x, y, z, w] of norm 1 (0.5 to 1.5 is "
                "normalized), got norm " +
                std::to_string(q.norm()));
  }
  return q.normalized();
}

// A trajectory from (t_ns, positions (N,3), quaternions xyzw (N,4)), the arrays named
// `prefix` + "t_ns", "p_W_I", "q_W_I_xyzw" in messages.
io::Trajectory TrajectoryFromArrays(py::handle t_ns_array, py::handle p_array, py::handle q_array,
                                    const std::string& prefix) {
  const Stamps t_ns = ToStamps(t_ns_array, prefix + "t_ns");
  const RowsX3 p = ToRows<3>(p_array, prefix + "p_W_I");
  const RowsX4 q = ToRows<4>(q_array, prefix + "q_W_I_xyzw");
  RequireRows(prefix + "p_W_I", p.rows(), t_ns.size());
  RequireRows(prefix + "q_W_I_xyzw", q.rows(), t_ns.size());
  io::Trajectory out(static_cast<size_t>(t_ns.size()));
  for (Eigen::Index k = 0; k < t_ns.size(); ++k) {
    out[k].t_ns = t_ns(k);
    out[k].T_W_I.p = p.row(k).transpose();
    out[k].T_W_I.q = FromXyzw(q.row(k).transpose(), prefix + "q_W_I_xyzw row " + std::to_string(k));
  }
  return out;
}

// ---- Calibration ----

// A quaternion's [x, y, z, w] as a read-only array: it is a copy (the setter checks the
// norm), so an element assigned in place would be lost; numpy refuses that instead.
py::array Xyzw(const Eigen::Quaterniond& q) {
  py::array_t<double> out(4);
  std::copy(q.coeffs().data(), q.coeffs().data() + 4, out.mutable_data());
  out.attr("setflags")(py::arg("write") = false);
  return std::move(out);
}

// A Vector3d member as a writable view (c.p_I_L_m[0] = 5.0 changes c) and a checked setter.
template <typename Class>
void BindVector3(py::class_<Class>& cls, const char* name, Eigen::Vector3d Class::*member) {
  cls.def_property(
      name, [member](Class& c) -> Eigen::Vector3d& { return c.*member; },
      [member, name](Class& c, const py::object& v) { c.*member = ToVector<3>(v, name); },
      py::return_value_policy::reference_internal);
}

// Dict-like views of the maps; a dict converts to them, so f.solver = {...} works too.
void BindMaps(py::module_& m) {
  py::bind_map<SolverSummary>(m, "SolverSummary").def(py::init([](const py::dict& d) {
    SolverSummary out;
    for (const auto& [key, value] : d) out[key.cast<std::string>()] = value.cast<std::string>();
    return out;
  }));
  py::bind_map<ResidualStatistics>(m, "ResidualStatistics").def(py::init([](const py::dict& d) {
    ResidualStatistics out;
    for (const auto& [key, value] : d) out[key.cast<std::string>()] = value.cast<double>();
    return out;
  }));
  py::bind_map<Residuals>(m, "Residuals").def(py::init([](const py::dict& d) {
    Residuals out;
    for (const auto& [key, value] : d) {
      out[key.cast<std::string>()] = value.cast<ResidualStatistics>();
    }
    return out;
  }));
  py::implicitly_convertible<py::dict, SolverSummary>();
  py::implicitly_convertible<py::dict, ResidualStatistics>();
  py::implicitly_convertible<py::dict, Residuals>();
}

void BindCalibration(py::module_& m) {
  py::class_<sensors::Calibration> calibration(
      m, "Calibration",
      "autocal's calibration values (names and units as in calibration.yaml; quaternions [x, y, "
      "z, w], Hamilton)");
  calibration.def(py::init<>())
      .def_property(
          "q_I_L_xyzw", [](const sensors::Calibration& c) { return Xyzw(c.q_I_L); },
          [](sensors::Calibration& c, const py::object& v) {
            c.q_I_L = FromXyzw(ToVector<4>(v, "q_I_L_xyzw"), "q_I_L_xyzw");
          })
      .def_readwrite("time_offset_lidar_imu_s", &sensors::Calibration::time_offset_lidar_imu_s)
      .def_property(
          "q_I_V_xyzw", [](const sensors::Calibration& c) { return Xyzw(c.q_I_V); },
          [](sensors::Calibration& c, const py::object& v) {
            c.q_I_V = FromXyzw(ToVector<4>(v, "q_I_V_xyzw"), "q_I_V_xyzw");
          })
      .def_readwrite("wheel_radius_left_m", &sensors::Calibration::wheel_radius_left_m)
      .def_readwrite("wheel_radius_right_m", &sensors::Calibration::wheel_radius_right_m)
      .def_readwrite("track_width_m", &sensors::Calibration::track_width_m)
      .def_readwrite("wheel_speed_scale_left", &sensors::Calibration::wheel_speed_scale_left)
      .def_readwrite("wheel_speed_scale_right", &sensors::Calibration::wheel_speed_scale_right)
      .def_readwrite("odometry_speed_scale", &sensors::Calibration::odometry_speed_scale)
      .def_readwrite("effective_track_m", &sensors::Calibration::effective_track_m)
      .def_readwrite("time_offset_wheel_imu_s", &sensors::Calibration::time_offset_wheel_imu_s)
      .def_readwrite("time_offset_gnss_imu_s", &sensors::Calibration::time_offset_gnss_imu_s);
  BindVector3(calibration, "p_I_L_m", &sensors::Calibration::p_I_L);
  BindVector3(calibration, "p_I_V_m", &sensors::Calibration::p_I_V);
  BindVector3(calibration, "p_I_A_m", &sensors::Calibration::p_I_A);

  BindMaps(m);
  py::class_<io::CalibrationFile>(m, "CalibrationFile",
                                  "calibration.yaml: the values, their sigma and observability")
      .def(py::init<>())
      .def_readwrite("value", &io::CalibrationFile::value)
      .def_readwrite("solver", &io::CalibrationFile::solver)
      .def_readwrite("residuals", &io::CalibrationFile::residuals)
      .def_property_readonly("sigma", [](const io::CalibrationFile& f) {
        const io::CalibrationUncertainty& u = f.uncertainty;
        py::dict d;
        if (u.T_I_L.sigma_rot_deg) d["T_I_L_rotation_deg"] = *u.T_I_L.sigma_rot_deg;
        if (u.T_I_L.sigma_p_m) d["T_I_L_translation_m"] = *u.T_I_L.sigma_p_m;
        if (u.T_I_V.sigma_rot_deg) d["T_I_V_rotation_deg"] = *u.T_I_V.sigma_rot_deg;
        if (u.T_I_V.sigma_p_m) d["T_I_V_translation_m"] = *u.T_I_V.sigma_p_m;
        if (u.p_I_A_m.sigma) d["p_I_A_m"] = *u.p_I_A_m.sigma;
        const std::pair<const char*, const io::ScalarBlockInfo*> scalars[] = {
            {"time_offset_lidar_imu_s", &u.time_offset_lidar_imu_s},
            {"wheel_radius_left_m", &u.wheel_radius_left_m},
            {"wheel_radius_right_m", &u.wheel_radius_right_m},
            {"track_width_m", &u.track_width_m},
            {"wheel_speed_scale_left", &u.wheel_speed_scale_left},
            {"wheel_speed_scale_right", &u.wheel_speed_scale_right},
            {"odometry_speed_scale", &u.odometry_speed_scale},
            {"effective_track_m", &u.effective_track_m},
            {"time_offset_wheel_imu_s", &u.time_offset_wheel_imu_s},
            {"time_offset_gnss_imu_s", &u.time_offset_gnss_imu_s}};
        for (const auto& [name, info] : scalars) {
          if (info->sigma) d[name] = *info->sigma;
        }
        return d;
      });

  m.def(
      "read_trajectory",
      [](const std::string& path) { return TrajectoryDict(io::ReadTumTrajectory(path)); },
      py::arg("path"), "a trajectory.tum (T_W_I on the IMU clock) as t_ns, p_W_I, q_W_I_xyzw");
  m.def(
      "write_trajectory",
      [](const std::string& path, const py::object& t_ns, const py::object& p,
         const py::object& q) {
        io::WriteTumTrajectory(path, TrajectoryFromArrays(t_ns, p, q, ""));
      },
      py::arg("path"), py::arg("t_ns"), py::arg("p_W_I"), py::arg("q_W_I_xyzw"),
      "writes a TUM trajectory (what autocal_evaluate reads)");
  m.def(
      "export_calibration",
      [](const io::CalibrationFile& result, const std::string& format,
         const std::string& vehicle_frame, const std::string& imu_frame,
         const std::string& lidar_frame, const std::string& gnss_frame) {
        io::ExportOptions options;
        options.vehicle_frame = vehicle_frame;
        options.imu_frame = imu_frame;
        options.lidar_frame = lidar_frame;
        options.gnss_frame = gnss_frame;
        return io::ExportCalibration(result, io::ParseExportFormat(format), options);
      },
      py::arg("result"), py::arg("format"), py::arg("vehicle_frame") = "base_link",
      py::arg("imu_frame") = "imu_link", py::arg("lidar_frame") = "lidar_link",
      py::arg("gnss_frame") = "gnss_link",
      "the text autocal_export writes (docs/export.md): kalibr, fast_lio, lio_sam, autoware, "
      "urdf, ros2_static_tf");
  m.def("read_calibration", &io::ReadCalibrationYaml, py::arg("path"),
        "reads a calibration.yaml (a result, or a dataset's ground truth)");
  m.def("write_calibration", &io::WriteCalibrationYaml, py::arg("path"), py::arg("calibration"),
        "writes a CalibrationFile as calibration.yaml (atomically, values round-trip exactly)");
}

// ---- Dataset ----

// Reads a written dataset as read_dataset does, so that what it would refuse (stamps not in
// nanoseconds, an IMU in other units) is reported by the write rather than by a later read.
void ReadBack(const std::string& directory) {
  try {
    io::ReadDataset(directory);
  } catch (const Error& e) {
    throw Error("write_dataset: '" + directory +
                "' was written, but the dataset reader refuses it: " + e.what());
  }
}

void BindDataset(py::module_& m) {
  py::class_<io::Dataset>(m, "Dataset",
                          "a dataset directory (datasets/README.md); arrays are copies")
      .def(py::init<>())
      .def_readonly("directory", &io::Dataset::directory)
      .def_property(
          "nominal",
          [](io::Dataset& d) -> sensors::Calibration& { return d.sensors.nominal_calibration; },
          [](io::Dataset& d, const sensors::Calibration& c) { d.sensors.nominal_calibration = c; },
          py::return_value_policy::reference_internal)
      .def_property_readonly("imu_t_ns",
                             [](const io::Dataset& d) {
                               return StampsOf(d.imu,
                                               [](const sensors::ImuSample& s) { return s.t_ns; });
                             })
      .def_property_readonly("imu_gyro_rad_s",
                             [](const io::Dataset& d) {
                               return RowsOf<3>(d.imu, [](const sensors::ImuSample& s) {
                                 return s.gyro_rad_s.transpose();
                               });
                             })
      .def_property_readonly("imu_accel_m_s2",
                             [](const io::Dataset& d) {
                               return RowsOf<3>(d.imu, [](const sensors::ImuSample& s) {
                                 return s.accel_m_s2.transpose();
                               });
                             })
      .def(
          "set_imu",
          [](io::Dataset& d, const py::object& t_ns, const py::object& gyro,
             const py::object& accel) { d.imu = ImuFromArrays(t_ns, gyro, accel); },
          py::arg("t_ns"), py::arg("gyro_rad_s"), py::arg("accel_m_s2"))
      .def_property_readonly("gnss_t_ns",
                             [](const io::Dataset& d) {
                               return StampsOf(d.gnss,
                                               [](const sensors::GnssFix& f) { return f.t_ns; });
                             })
      .def_property_readonly("gnss_lat_lon_alt",
                             [](const io::Dataset& d) {
                               return RowsOf<3>(d.gnss, [](const sensors::GnssFix& f) {
                                 return Eigen::RowVector3d(f.lat_deg, f.lon_deg, f.alt_m);
                               });
                             })
      .def_property_readonly("gnss_std_enu_m",
                             [](const io::Dataset& d) {
                               return RowsOf<3>(d.gnss, [](const sensors::GnssFix& f) {
                                 return f.std_enu_m.transpose();
                               });
                             })
      .def(
          "set_gnss",
          [](io::Dataset& d, const py::object& t_ns, const py::object& lat_lon_alt,
             const py::object& std_enu) {
            d.gnss = GnssFromArrays(t_ns, lat_lon_alt, std_enu);
            if (!d.sensors.gnss) d.sensors.gnss = sensors::GnssConfig();
          },
          py::arg("t_ns"), py::arg("lat_lon_alt"), py::arg("std_enu_m"))
      .def_property_readonly(
          "odometry_t_ns",
          [](const io::Dataset& d) {
            return StampsOf(d.odometry, [](const sensors::OdometrySample& s) { return s.t_ns; });
          })
      .def_property_readonly("odometry_speed_yaw_rate",
                             [](const io::Dataset& d) {
                               return RowsOf<2>(d.odometry, [](const sensors::OdometrySample& s) {
                                 return Eigen::RowVector2d(s.speed_m_s, s.yaw_rate_rad_s);
                               });
                             })
      .def_property_readonly("wheel_t_ns",
                             [](const io::Dataset& d) {
                               return StampsOf(
                                   d.wheel, [](const sensors::WheelSample& s) { return s.t_ns; });
                             })
      .def_property_readonly("wheel_rad_s",
                             [](const io::Dataset& d) {
                               return RowsOf<2>(d.wheel, [](const sensors::WheelSample& s) {
                                 return Eigen::RowVector2d(s.left_rad_s, s.right_rad_s);
                               });
                             })
      .def_property_readonly(
          "groundtruth_trajectory",
          [](const io::Dataset& d) { return TrajectoryDict(d.groundtruth_trajectory); })
      .def_property_readonly("lidar_sweeps",
                             [](const io::Dataset& d) { return d.lidar_sweeps.size(); })
      .def(
          "load_sweep",
          [](const io::Dataset& d, size_t index) {
            if (index >= d.lidar_sweeps.size()) {
              throw Error("load_sweep: sweep " + std::to_string(index) + " of " +
                          std::to_string(d.lidar_sweeps.size()));
            }
            const lidar::LidarSweep sweep = d.LoadSweep(index);
            py::dict out;
            out["t_ns"] = sweep.t_ns;
            out["points"] = RowsX3(sweep.cloud.points.transpose());
            out["time_s"] = sweep.cloud.time_s;
            out["intensity"] = sweep.cloud.intensity;
            return out;
          },
          py::arg("index"),
          "one sweep read from disk: t_ns (LiDAR clock), points (N,3) in the sensor frame, "
          "time_s after the stamp and intensity (empty when the file has none)");

  m.def(
      "read_dataset", [](const std::string& directory) { return io::ReadDataset(directory); },
      py::arg("directory"), "reads and validates a dataset directory (sweeps stay on disk)");
  m.def(
      "write_dataset",
      [](const std::string& directory, const io::Dataset& d) {
        if (!d.lidar_sweeps.empty()) {
          throw Error(
              "write_dataset: datasets with LiDAR sweeps are written by autocal_import "
              "or autocal_simulate");
        }
        if (d.imu.empty()) throw Error("write_dataset: the dataset has no IMU samples (set_imu)");
        io::DatasetWriter writer(directory);
        writer.WriteSensorsConfig(d.sensors);
        writer.WriteImu(d.imu);
        if (!d.wheel.empty()) writer.WriteWheel(d.wheel);
        if (!d.wheel_speeds.empty()) writer.WriteWheelSpeeds(d.wheel_speeds);
        if (!d.odometry.empty()) writer.WriteOdometry(d.odometry);
        if (!d.gnss.empty()) writer.WriteGnss(d.gnss);
        writer.Close();
        ReadBack(directory);
      },
      py::arg("directory"), py::arg("dataset"),
      "writes a dataset without LiDAR (IMU, wheel data in its form, GNSS, sensors.yaml) and "
      "reads it back: raises autocal.Error when read_dataset would refuse it");
}

// ---- Calibration and online estimation ----

// Calls a Python progress callback from the library with the GIL held; its exception ends
// the run and reaches the caller.
template <typename Progress>
std::function<void(const Progress&)> WithGil(std::function<void(const Progress&)> callback) {
  if (!callback) return nullptr;
  return [callback](const Progress& p) {
    py::gil_scoped_acquire gil;
    callback(p);
  };
}

void BindPipeline(py::module_& m) {
  py::class_<pipeline::CalibrationProgress>(m, "CalibrationProgress")
      .def_readonly("stage", &pipeline::CalibrationProgress::stage)
      .def_readonly("fraction", &pipeline::CalibrationProgress::fraction)
      .def_readonly("cost", &pipeline::CalibrationProgress::cost)
      .def_readonly("seconds_left", &pipeline::CalibrationProgress::seconds_left);
  py::class_<pipeline::OnlineEstimationProgress>(m, "OnlineEstimationProgress")
      .def_readonly("log_fraction", &pipeline::OnlineEstimationProgress::log_fraction)
      .def_readonly("updates", &pipeline::OnlineEstimationProgress::updates)
      .def_readonly("calibration", &pipeline::OnlineEstimationProgress::calibration);

  py::class_<pipeline::OfflineCalibrationResult>(m, "CalibrationResult")
      .def_readonly("calibration", &pipeline::OfflineCalibrationResult::calibration)
      .def_readonly("warnings", &pipeline::OfflineCalibrationResult::warnings)
      .def_readonly("seconds_total", &pipeline::OfflineCalibrationResult::seconds_total)
      .def_property_readonly(
          "trajectory",
          [](const pipeline::OfflineCalibrationResult& r) { return TrajectoryDict(r.trajectory); })
      .def(
          "write",
          [](const pipeline::OfflineCalibrationResult& r, const std::string& directory) {
            pipeline::WriteCalibrationResult(directory, r);
          },
          py::arg("directory"), "writes the result files autocal_calibrate writes");

  py::class_<pipeline::OnlineEstimationResult>(m, "OnlineEstimationResult")
      .def_readonly("calibration", &pipeline::OnlineEstimationResult::calibration)
      .def_readonly("warnings", &pipeline::OnlineEstimationResult::warnings)
      .def_property_readonly(
          "trajectory",
          [](const pipeline::OnlineEstimationResult& r) { return TrajectoryDict(r.trajectory); })
      .def(
          "write",
          [](const pipeline::OnlineEstimationResult& r, const std::string& directory) {
            pipeline::WriteOnlineEstimationResult(directory, r);
          },
          py::arg("directory"), "writes the result files autocal_estimate writes");

  m.def(
      "calibrate",
      [](const std::string& dataset, const std::string& problem,
         std::function<void(const pipeline::CalibrationProgress&)> progress) {
        const io::Dataset d = io::ReadDataset(dataset);
        const io::Problem p = io::ReadProblemYaml(problem);
        pipeline::OfflineCalibrationOptions options;
        options.progress = WithGil(std::move(progress));
        py::gil_scoped_release release;
        return pipeline::CalibrateDataset(d, p, options);
      },
      py::arg("dataset"), py::arg("problem"), py::arg("progress") = nullptr,
      "autocal_calibrate as a call: dataset directory, problem file, optional progress(p)");
  py::class_<pipeline::BlockRepeatability>(m, "BlockRepeatability")
      .def_readonly("name", &pipeline::BlockRepeatability::name)
      .def_readonly("agree", &pipeline::BlockRepeatability::agree)
      .def_readonly("finding", &pipeline::BlockRepeatability::finding)
      .def_property_readonly(
          "chi_square",
          [](const pipeline::BlockRepeatability& r) { return r.agreement.chi_square; })
      .def_property_readonly(
          "degrees_of_freedom",
          [](const pipeline::BlockRepeatability& r) { return r.agreement.degrees_of_freedom; })
      .def_property_readonly(
          "p_value", [](const pipeline::BlockRepeatability& r) { return r.agreement.p_value; });
  py::class_<pipeline::MultiLogCalibrationResult>(m, "MultiLogCalibrationResult")
      .def_readonly("calibration", &pipeline::MultiLogCalibrationResult::calibration)
      .def_readonly("repeatability", &pipeline::MultiLogCalibrationResult::repeatability)
      .def_readonly("warnings", &pipeline::MultiLogCalibrationResult::warnings)
      .def_property_readonly("logs",
                             [](const pipeline::MultiLogCalibrationResult& r) {
                               py::list logs;
                               for (const pipeline::LogCalibration& log : r.logs) {
                                 py::dict d;
                                 d["name"] = log.name;
                                 d["own"] = log.own;
                                 d["trajectory"] = TrajectoryDict(log.at_shared.trajectory);
                                 logs.append(d);
                               }
                               return logs;
                             })
      .def(
          "write",
          [](const pipeline::MultiLogCalibrationResult& r, const std::string& directory) {
            pipeline::WriteMultiLogResult(directory, r);
          },
          py::arg("directory"),
          "writes the result files autocal_calibrate writes for several logs");
  m.def(
      "calibrate_logs",
      [](const std::vector<std::string>& datasets, const std::string& problem,
         std::function<void(const pipeline::CalibrationProgress&)> progress) {
        std::vector<io::Dataset> d;
        for (const std::string& directory : datasets) d.push_back(io::ReadDataset(directory));
        const io::Problem p = io::ReadProblemYaml(problem);
        pipeline::MultiLogCalibrationOptions options;
        options.calibration.progress = WithGil(std::move(progress));
        py::gil_scoped_release release;
        return pipeline::CalibrateDatasets(d, p, options);
      },
      py::arg("datasets"), py::arg("problem"), py::arg("progress") = nullptr,
      "several logs of one vehicle: one shared calibration, each log's own, their repeatability");
  m.def(
      "fleet_report",
      [](const std::vector<std::string>& result_directories) {
        const pipeline::FleetReport report = pipeline::GatherFleet(result_directories);
        py::dict out;
        py::list runs;
        for (size_t e = 0; e < report.entries.size(); ++e) {
          const pipeline::FleetEntry& entry = report.entries[e];
          py::dict run;
          run["vehicle"] = entry.vehicle;
          run["directory"] = entry.directory;
          run["failure"] = entry.failure;
          py::dict values;
          for (size_t c = 0; c < report.columns.size(); ++c) {
            values[py::str(report.columns[c].name)] =
                py::make_tuple(report.values[e][c], report.sigmas[e][c]);
          }
          run["values"] = values;
          runs.append(run);
        }
        py::list outliers;
        for (const pipeline::FleetOutlier& o : report.outliers) outliers.append(o.text);
        out["runs"] = runs;
        out["outliers"] = outliers;
        out["csv"] = pipeline::FleetCsv(report);
        out["html"] = pipeline::FleetReportHtml(report);
        return out;
      },
      py::arg("result_directories"),
      "autocal_fleet_report as a call: per run its vehicle, failure and (value, sigma) by column; "
      "the outliers in words; the table and overview as text");
  m.def(
      "estimate_online",
      [](const std::string& dataset, const std::string& problem,
         std::function<void(const pipeline::OnlineEstimationProgress&)> progress) {
        const io::Dataset d = io::ReadDataset(dataset);
        const io::Problem p = io::ReadProblemYaml(problem);
        pipeline::OnlineEstimationOptions options;
        options.progress = WithGil(std::move(progress));
        py::gil_scoped_release release;
        return pipeline::EstimateDatasetOnline(d, p, options);
      },
      py::arg("dataset"), py::arg("problem"), py::arg("progress") = nullptr,
      "autocal_estimate as a call: dataset directory, problem file, optional progress(p)");
}

// ---- Preintegration, registration, evaluation ----

void BindAlgorithms(py::module_& m) {
  m.def(
      "preintegrate",
      [](const py::object& t_ns, const py::object& gyro, const py::object& accel,
         int64_t t_start_ns, int64_t t_end_ns, double gyroscope_noise_density,
         double accelerometer_noise_density, double gyroscope_random_walk,
         double accelerometer_random_walk, double gravity_m_s2, const py::object& b_g,
         const py::object& b_a) {
        sensors::ImuNoise noise;
        noise.gyroscope_noise_density = gyroscope_noise_density;
        noise.accelerometer_noise_density = accelerometer_noise_density;
        noise.gyroscope_random_walk = gyroscope_random_walk;
        noise.accelerometer_random_walk = accelerometer_random_walk;
        sensors::PreintegrationOptions options;
        options.gravity_m_s2 = gravity_m_s2;
        sensors::ImuPreintegration pre(noise, options, ToVector<3>(b_g, "b_g"),
                                       ToVector<3>(b_a, "b_a"));
        pre.Integrate(ImuFromArrays(t_ns, gyro, accel), t_start_ns, t_end_ns);
        py::dict d;
        d["dt_s"] = pre.dt_s();
        d["delta_R"] = pre.delta_R();
        d["delta_v"] = pre.delta_v();
        d["delta_p"] = pre.delta_p();
        d["covariance"] = Eigen::MatrixXd(pre.Covariance());
        return d;
      },
      py::arg("t_ns"), py::arg("gyro_rad_s"), py::arg("accel_m_s2"), py::arg("t_start_ns"),
      py::arg("t_end_ns"), py::arg("gyroscope_noise_density") = 1.6968e-4,
      py::arg("accelerometer_noise_density") = 2.0e-3, py::arg("gyroscope_random_walk") = 1.9393e-5,
      py::arg("accelerometer_random_walk") = 3.0e-3, py::arg("gravity_m_s2") = 9.80665,
      py::arg("b_g") = std::vector<double>(3, 0.0), py::arg("b_a") = std::vector<double>(3, 0.0),
      "IMU preintegration over [t_start_ns, t_end_ns] (docs/factors.md, Eq. F3-F5): dt_s, "
      "delta_R, delta_v, delta_p and the 15x15 covariance of [dphi, dv, dp, dbg, dba]");

  m.def(
      "register",
      [](const py::object& source_array, const py::object& target_array,
         const py::object& init_array, const std::string& method, const std::string& loss,
         double loss_scale_m, double voxel_m, double max_correspondence_m, int max_iterations,
         int num_threads) {
        lidar::RegistrationOptions setting = lidar::MakeRegistrationOptions(
            method, loss, loss_scale_m, voxel_m, max_correspondence_m);
        if (max_iterations < 1 || num_threads < 1) {
          throw Error("register: max_iterations and num_threads must be at least 1");
        }
        setting.icp.convergence.max_iterations = max_iterations;
        setting.icp.num_threads = num_threads;
        lidar::PointCloud s, t;
        s.points = ToRows<3>(source_array, "source").transpose();
        t.points = ToRows<3>(target_array, "target").transpose();
        const RowsX4 init = ToRows<4>(init_array, "init");
        if (init.rows() != 4) {
          throw Error("init: expected a (4, 4) array, got " + std::to_string(init.rows()) +
                      " rows");
        }
        const geometry::Pose3d guess =
            lidar::PoseGuessFromMatrix(Eigen::Matrix4d(init), "register: init");
        lidar::RegistrationResult r;
        {
          py::gil_scoped_release release;
          r = lidar::RegisterPointClouds(s, t, guess, setting);
        }
        py::dict d;
        d["T_target_source"] = r.icp.T_target_source.Matrix();
        d["covariance"] = Eigen::MatrixXd(r.icp.covariance);
        d["converged"] = r.icp.converged;
        d["iterations"] = r.icp.iterations;
        d["inlier_rmse_m"] = r.icp.inlier_rmse_m;
        d["fitness"] = r.icp.fitness;
        return d;
      },
      py::arg("source"), py::arg("target"),
      py::arg("init") =
          std::vector<std::vector<double>>{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}},
      py::arg("method") = "point_to_plane", py::arg("loss") = "none", py::arg("loss_scale_m") = 0.1,
      py::arg("voxel_m") = 0.25, py::arg("max_correspondence_m") = 1.0,
      py::arg("max_iterations") = 30, py::arg("num_threads") = 1,
      "aligns source (N,3) to target (M,3) as autocal_register does (docs/lidar.md): "
      "T_target_source (4x4), covariance (6x6, [rho; phi]), converged, iterations, "
      "inlier_rmse_m, fitness");

  m.def(
      "compare_calibration",
      [](const sensors::Calibration& estimate, const sensors::Calibration& truth) {
        const evaluation::CalibrationErrors e = evaluation::CompareCalibration(estimate, truth);
        py::dict d;
        d["T_I_L_rotation_deg"] = e.T_I_L.rotation_deg;
        d["T_I_L_translation_mm"] = e.T_I_L.translation_mm;
        d["time_offset_ms"] = e.time_offset_ms;
        d["wheel_radius_left_percent"] = e.wheel_radius_left_percent;
        d["wheel_radius_right_percent"] = e.wheel_radius_right_percent;
        d["track_width_percent"] = e.track_width_percent;
        d["wheel_speed_scale_left_percent"] = e.wheel_speed_scale_left_percent;
        d["wheel_speed_scale_right_percent"] = e.wheel_speed_scale_right_percent;
        d["odometry_speed_scale_percent"] = e.odometry_speed_scale_percent;
        d["effective_track_percent"] = e.effective_track_percent;
        d["p_I_A_mm"] = e.p_I_A_mm;
        d["T_I_V_rotation_deg"] = e.T_I_V.rotation_deg;
        d["T_I_V_translation_mm"] = e.T_I_V.translation_mm;
        d["wheel_time_offset_ms"] = e.wheel_time_offset_ms;
        d["gnss_time_offset_ms"] = e.gnss_time_offset_ms;
        return d;
      },
      py::arg("estimate"), py::arg("truth"),
      "estimate minus truth per block (docs/evaluation.md, \"Calibration\"), every field of "
      "evaluation::CalibrationErrors");
  m.def(
      "compare_trajectory",
      [](const py::object& est_t, const py::object& est_p, const py::object& est_q,
         const py::object& true_t, const py::object& true_p, const py::object& true_q) {
        const evaluation::TrajectoryErrors e =
            evaluation::CompareTrajectory(TrajectoryFromArrays(est_t, est_p, est_q, ""),
                                          TrajectoryFromArrays(true_t, true_p, true_q, "true_"));
        py::dict d;
        d["matched_poses"] = e.matched_poses;
        d["exact_matches"] = e.exact_matches;
        d["unmatched_poses"] = e.unmatched_poses;
        d["alignment_yaw_rad"] = e.alignment.yaw_rad;
        d["alignment_translation_m"] = Eigen::VectorXd(e.alignment.translation_m);
        d["alignment_yaw_from_orientation"] = e.alignment.yaw_from_orientation;
        d["ate_translation_rmse_m"] = e.ate_translation_rmse_m;
        d["ate_rotation_rmse_deg"] = e.ate_rotation_rmse_deg;
        d["tilt_rmse_deg"] = e.tilt_rmse_deg;
        d["max_translation_error_m"] = e.max_translation_error_m;
        d["max_rotation_error_deg"] = e.max_rotation_error_deg;
        return d;
      },
      py::arg("t_ns"), py::arg("p_W_I"), py::arg("q_W_I_xyzw"), py::arg("true_t_ns"),
      py::arg("true_p_W_I"), py::arg("true_q_W_I_xyzw"),
      "ATE after a 4-DoF (yaw + translation) alignment (docs/evaluation.md): every field of "
      "evaluation::TrajectoryErrors, the alignment's as alignment_yaw_rad, "
      "alignment_translation_m and alignment_yaw_from_orientation");
}

}  // namespace
}  // namespace python
}  // namespace autocal

PYBIND11_MODULE(autocal, m) {
  m.doc() = "autocal: LiDAR-IMU-wheel-GNSS calibration (https: see README.md)";
  py::register_exception<autocal::Error>(m, "Error", PyExc_RuntimeError);
  autocal::python::BindCalibration(m);
  autocal::python::BindDataset(m);
  autocal::python::BindPipeline(m);
  autocal::python::BindAlgorithms(m);
}
