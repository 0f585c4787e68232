"""Tests of the Python module `autocal` (docs/python.md), run by ctest as python.module.

Each test checks numbers against a closed form or the ground truth of a simulated log."""

import math
import os
import shutil
import subprocess
import tempfile
import unittest

import numpy as np

import autocal


def rot_z(angle_rad):
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def output_dir(name):
    root = os.environ.get("AUTOCAL_TEST_OUTPUT_DIR", tempfile.gettempdir())
    path = os.path.join(root, name)
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


class CalibrationFiles(unittest.TestCase):
    def test_values_round_trip_through_calibration_yaml(self):
        f = autocal.CalibrationFile()
        f.value.q_I_L_xyzw = np.array([0.0, 0.0, math.sin(0.3), math.cos(0.3)])
        f.value.p_I_L_m = np.array([0.3, -0.05, 0.55])
        f.value.time_offset_lidar_imu_s = 0.025
        f.value.wheel_radius_left_m = 0.3335
        path = os.path.join(output_dir("calibration"), "calibration.yaml")
        autocal.write_calibration(path, f)
        back = autocal.read_calibration(path)
        np.testing.assert_array_equal(back.value.q_I_L_xyzw, f.value.q_I_L_xyzw)
        np.testing.assert_array_equal(back.value.p_I_L_m, [0.3, -0.05, 0.55])
        self.assertEqual(back.value.time_offset_lidar_imu_s, 0.025)
        self.assertEqual(back.value.wheel_radius_left_m, 0.3335)

    def test_exports_as_autocal_export_does(self):
        f = autocal.CalibrationFile()
        f.value.p_I_L_m = np.array([1.0, 2.0, 3.0])
        with self.assertRaises(autocal.Error):  # no LiDAR block was estimated
            autocal.export_calibration(f, "fast_lio")
        path = os.path.join(output_dir("export"), "calibration.yaml")
        autocal.write_calibration(path, f)
        with open(path) as yaml_file:  # mark the LiDAR block as estimated: give it a sigma
            text = yaml_file.read().replace("  p_m: [1, 2, 3]\n",
                                            "  p_m: [1, 2, 3]\n  sigma_rot_deg: [0.1, 0.1, 0.1]\n", 1)
        with open(path, "w") as yaml_file:
            yaml_file.write(text)
        text = autocal.export_calibration(autocal.read_calibration(path), "fast_lio")
        self.assertIn("extrinsic_T: [1, 2, 3]", text)

    def test_fields_are_assigned_in_place(self):
        f = autocal.CalibrationFile()
        f.value.p_I_L_m[2] = 0.55
        f.solver["termination"] = "CONVERGENCE"
        f.residuals["gnss"] = {"rms_m": 0.4}
        f.residuals["gnss"]["count"] = 12.0
        path = os.path.join(output_dir("calibration_in_place"), "calibration.yaml")
        autocal.write_calibration(path, f)
        back = autocal.read_calibration(path)
        np.testing.assert_array_equal(back.value.p_I_L_m, [0.0, 0.0, 0.55])
        self.assertEqual(dict(back.solver), {"termination": "CONVERGENCE"})
        self.assertEqual(dict(back.residuals["gnss"]), {"rms_m": 0.4, "count": 12.0})
        back.solver = {"iterations": "14"}  # whole maps are assigned as dicts
        self.assertEqual(dict(back.solver), {"iterations": "14"})
        with self.assertRaises(ValueError):  # a copy: refused rather than lost
            back.value.q_I_L_xyzw[0] = 0.5
        np.testing.assert_array_equal(back.value.q_I_L_xyzw, [0.0, 0.0, 0.0, 1.0])

    def test_compare_calibration_returns_every_block(self):
        truth = autocal.Calibration()
        estimate = autocal.Calibration()
        estimate.time_offset_lidar_imu_s = 0.001
        estimate.wheel_radius_left_m = 1.01 * truth.wheel_radius_left_m
        estimate.wheel_radius_right_m = 0.99 * truth.wheel_radius_right_m
        estimate.track_width_m = 1.02 * truth.track_width_m
        estimate.wheel_speed_scale_left = 1.03
        estimate.wheel_speed_scale_right = 0.97
        estimate.odometry_speed_scale = 1.04
        estimate.effective_track_m = 1.05 * truth.effective_track_m
        estimate.p_I_A_m = [0.0, 0.0, 0.002]
        estimate.p_I_L_m = [0.003, 0.0, 0.0]
        estimate.p_I_V_m = [0.0, 0.004, 0.0]
        estimate.time_offset_wheel_imu_s = 0.005
        estimate.time_offset_gnss_imu_s = -0.006
        e = autocal.compare_calibration(estimate, truth)
        self.assertEqual(list(e), [
            "T_I_L_rotation_deg", "T_I_L_translation_mm", "time_offset_ms",
            "wheel_radius_left_percent", "wheel_radius_right_percent", "track_width_percent",
            "wheel_speed_scale_left_percent", "wheel_speed_scale_right_percent",
            "odometry_speed_scale_percent", "effective_track_percent", "p_I_A_mm",
            "T_I_V_rotation_deg", "T_I_V_translation_mm", "wheel_time_offset_ms",
            "gnss_time_offset_ms"])
        scalars = {"time_offset_ms": 1.0, "wheel_radius_left_percent": 1.0,
                   "wheel_radius_right_percent": -1.0, "track_width_percent": 2.0,
                   "wheel_speed_scale_left_percent": 3.0, "wheel_speed_scale_right_percent": -3.0,
                   "odometry_speed_scale_percent": 4.0, "effective_track_percent": 5.0,
                   "wheel_time_offset_ms": 5.0, "gnss_time_offset_ms": -6.0}
        for name, value in scalars.items():
            self.assertAlmostEqual(e[name], value, places=9, msg=name)
        np.testing.assert_allclose(e["p_I_A_mm"], [0, 0, 2], atol=1e-12)
        np.testing.assert_allclose(e["T_I_L_translation_mm"], [3, 0, 0], atol=1e-12)
        np.testing.assert_allclose(e["T_I_V_translation_mm"], [0, 4, 0], atol=1e-12)
        np.testing.assert_array_equal(e["T_I_L_rotation_deg"], [0, 0, 0])

    def test_a_missing_file_raises_autocal_error(self):
        with self.assertRaises(autocal.Error):
            autocal.read_calibration("/nonexistent/calibration.yaml")


class Datasets(unittest.TestCase):
    def test_imu_and_gnss_round_trip_through_a_dataset_directory(self):
        n = 400
        t_ns = 1_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000  # 200 Hz
        rng = np.random.default_rng(3)
        gyro = 0.01 * rng.standard_normal((n, 3))
        accel = np.array([0.0, 0.0, 9.81]) + 0.02 * rng.standard_normal((n, 3))
        d = autocal.Dataset()
        d.set_imu(t_ns, gyro, accel)
        fixes = t_ns[::20]
        lla = np.column_stack([49.0 + 1e-6 * np.arange(len(fixes)), np.full(len(fixes), 8.4),
                               np.full(len(fixes), 165.0)])
        d.set_gnss(fixes, lla, np.full((len(fixes), 3), 0.5))
        directory = output_dir("dataset")
        autocal.write_dataset(directory, d)
        back = autocal.read_dataset(directory)
        np.testing.assert_array_equal(back.imu_t_ns, t_ns)
        np.testing.assert_array_equal(back.imu_gyro_rad_s, gyro)
        np.testing.assert_array_equal(back.imu_accel_m_s2, accel)
        np.testing.assert_array_equal(back.gnss_t_ns, fixes)
        np.testing.assert_array_equal(back.gnss_lat_lon_alt, lla)

    def test_the_nominal_calibration_is_assigned_in_place(self):
        d = autocal.Dataset()
        d.set_imu(1_000_000_000 + 5_000_000 * np.arange(20), np.zeros((20, 3)),
                  np.tile([0.0, 0.0, 9.81], (20, 1)))
        d.nominal.track_width_m = 2.5
        d.nominal.p_I_A_m[2] = 1.2
        self.assertEqual(d.nominal.track_width_m, 2.5)
        directory = output_dir("dataset_nominal")
        autocal.write_dataset(directory, d)
        back = autocal.read_dataset(directory).nominal
        self.assertEqual(back.track_width_m, 2.5)
        np.testing.assert_array_equal(back.p_I_A_m, [0.0, 0.0, 1.2])

    def test_mismatched_arrays_are_refused(self):
        d = autocal.Dataset()
        with self.assertRaises(autocal.Error):
            d.set_imu(np.arange(3, dtype=np.int64), np.zeros((2, 3)), np.zeros((3, 3)))
        with self.assertRaisesRegex(autocal.Error, r"gyro_rad_s: expected an \(N, 3\) array"):
            d.set_imu(np.arange(3, dtype=np.int64), np.zeros((3, 4)), np.zeros((3, 3)))


class ArrayChecks(unittest.TestCase):
    """Stamps are integer nanoseconds kept exactly, values real and finite: what the dataset
    readers accept, refused with the argument's name otherwise rather than cast."""

    def setUp(self):
        self.rates = np.zeros((2, 3))
        self.accel = np.tile([0.0, 0.0, 9.81], (2, 1))

    def test_stamps_that_are_not_integers_are_refused(self):
        d = autocal.Dataset()
        for stamps in [np.array([1.5, 2.7]), np.array([np.nan, 1.0]), np.array([1e30, 1.0]),
                       np.array([1.7e18, 1.7e18 + 256]), np.array([True, False]),
                       np.array([1 + 0j, 2 + 0j])]:
            with self.assertRaisesRegex(TypeError, "t_ns: .*dtype " + str(stamps.dtype)):
                d.set_imu(stamps, self.rates, self.accel)
        self.assertEqual(len(d.imu_t_ns), 0)
        with self.assertRaisesRegex(TypeError, "t_ns: .*float64"):
            autocal.preintegrate(np.array([0.0, 1e7]), self.rates, self.accel, 0, 10_000_000)
        with self.assertRaisesRegex(TypeError, "true_t_ns: .*float64"):
            autocal.compare_trajectory([0, 1], np.zeros((2, 3)), np.tile([0, 0, 0, 1.0], (2, 1)),
                                       np.array([0.0, 1.0]), np.zeros((2, 3)),
                                       np.tile([0, 0, 0, 1.0], (2, 1)))
        with self.assertRaisesRegex(TypeError, "t_ns: .*float64"):
            autocal.write_trajectory(os.path.join(output_dir("stamps"), "t.tum"),
                                     np.array([0.0, 1.0]), np.zeros((2, 3)),
                                     np.tile([0, 0, 0, 1.0], (2, 1)))

    def test_integer_stamps_are_kept_exactly(self):
        d = autocal.Dataset()
        d.set_imu([1_700_000_000_000_000_001, 1_700_000_000_000_000_002], self.rates, self.accel)
        self.assertEqual(d.imu_t_ns.dtype, np.int64)
        self.assertEqual(list(d.imu_t_ns), [1_700_000_000_000_000_001, 1_700_000_000_000_000_002])
        d.set_imu(np.array([5, 2**40], dtype=np.uint64), self.rates, self.accel)
        self.assertEqual(list(d.imu_t_ns), [5, 2**40])
        d.set_imu(np.array([-7, 3], dtype=np.int8), self.rates, self.accel)
        self.assertEqual(list(d.imu_t_ns), [-7, 3])

    def test_stamps_out_of_range_or_order_are_refused(self):
        d = autocal.Dataset()
        with self.assertRaisesRegex(autocal.Error, "t_ns: stamp 0 is 9223372036854775813 ns"):
            d.set_imu(np.array([2**63 + 5, 2**63 + 6], dtype=np.uint64), self.rates, self.accel)
        with self.assertRaisesRegex(autocal.Error, "146 years"):
            d.set_imu(np.array([-2**63, 0], dtype=np.int64), self.rates, self.accel)
        with self.assertRaisesRegex(autocal.Error, "t_ns: stamp 1 .* strictly increase"):
            d.set_imu(np.array([20, 10]), self.rates, self.accel)

    def test_values_that_are_not_finite_real_numbers_are_refused(self):
        d = autocal.Dataset()
        t_ns = np.array([1, 2])
        with self.assertRaisesRegex(TypeError, "gyro_rad_s: .*complex128"):
            d.set_imu(t_ns, self.rates + 1j, self.accel)
        with self.assertRaisesRegex(TypeError, "accel_m_s2: .*<U"):
            d.set_imu(t_ns, self.rates, self.accel.astype(str))
        accel = self.accel.copy()
        accel[1, 2] = np.nan
        with self.assertRaisesRegex(autocal.Error, "accel_m_s2: row 1 has a non-finite value"):
            d.set_imu(t_ns, self.rates, accel)
        with self.assertRaisesRegex(autocal.Error, "gyro_rad_s: row 1"):
            autocal.preintegrate(t_ns, np.array([[0, 0, 0], [np.inf, 0, 0]]), self.accel, 1, 2)
        with self.assertRaisesRegex(TypeError, "b_g: .*complex128"):
            autocal.preintegrate(t_ns, self.rates, self.accel, 1, 2, b_g=np.zeros(3) + 1j)
        self.assertEqual(len(d.imu_t_ns), 0)

    def test_gnss_fixes_are_refused_as_gnss_csv_refuses_them(self):
        d = autocal.Dataset()
        t_ns = np.array([1, 2])
        lla = np.array([[49.0, 8.4, 165.0], [91.0, 8.4, 165.0]])
        with self.assertRaisesRegex(autocal.Error, "lat_lon_alt: row 1: latitude"):
            d.set_gnss(t_ns, lla, np.full((2, 3), 0.5))
        with self.assertRaisesRegex(autocal.Error, "std_enu_m: row 0: a standard deviation"):
            d.set_gnss(t_ns, lla[:1].repeat(2, axis=0), np.array([[0.5, 0.0, 0.5], [0.5] * 3]))
        self.assertEqual(len(d.gnss_t_ns), 0)

    def test_quaternions_that_are_no_rotation_are_refused_with_their_row(self):
        t_ns = np.array([0, 1_000_000_000])
        p = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
        unit = np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))
        zero = unit.copy()
        zero[1] = 0.0
        with self.assertRaisesRegex(autocal.Error, r"^q_W_I_xyzw row 1: .* got norm 0"):
            autocal.compare_trajectory(t_ns, p, zero, t_ns, p, unit)
        with self.assertRaisesRegex(autocal.Error, r"^true_q_W_I_xyzw row 0: .* got norm 2"):
            autocal.compare_trajectory(t_ns, p, unit, t_ns, p, 2.0 * unit)
        with self.assertRaisesRegex(autocal.Error, r"^q_W_I_xyzw row 1"):
            autocal.write_trajectory(os.path.join(output_dir("quaternions"), "t.tum"), t_ns, p, zero)
        # Within (0.5, 1.5) a quaternion is normalized, as calibration.yaml's are.
        errors = autocal.compare_trajectory(t_ns, p, 1.2 * unit, t_ns, p, unit)
        self.assertEqual(errors["max_rotation_error_deg"], 0.0)
        self.assertEqual(errors["ate_rotation_rmse_deg"], 0.0)

    def test_compare_trajectory_gives_the_alignment_and_the_matches(self):
        # The truth on a 20 m square at 20 Hz; the estimate the same path turned 30 deg about z
        # and moved, stamped at the truth's samples, between two of them and past its end.
        true_t = 50_000_000 * np.arange(5)
        true_p = np.array([[0.0, 0, 0], [20, 0, 0], [20, 20, 0], [0, 20, 0], [0, 0, 0]])
        unit = np.tile([0.0, 0.0, 0.0, 1.0], (5, 1))
        yaw = np.radians(30.0)
        turn = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
        t = np.array([0, 50_000_000, 75_000_000, 150_000_000, 9_000_000_000])
        p = np.array([[0.0, 0, 0], [20, 0, 0], [20, 10, 0], [0, 20, 0], [0, 0, 0]])
        q = np.tile([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)], (5, 1))
        moved = p @ turn.T + [3.0, -2.0, 0.5]
        e = autocal.compare_trajectory(t, moved, q, true_t, true_p, unit)
        self.assertEqual(e["matched_poses"], 4)
        self.assertEqual(e["exact_matches"], 3)
        self.assertEqual(e["unmatched_poses"], 1)
        # The alignment maps the estimate onto the truth: the turn and shift undone.
        self.assertAlmostEqual(e["alignment_yaw_rad"], -yaw, places=9)
        np.testing.assert_allclose(e["alignment_translation_m"], -turn.T @ [3.0, -2.0, 0.5],
                                   atol=1e-9)
        self.assertFalse(e["alignment_yaw_from_orientation"])
        self.assertLess(e["ate_translation_rmse_m"], 1e-9)

    def test_write_dataset_refuses_what_read_dataset_refuses(self):
        directory = output_dir("refused_dataset")
        with self.assertRaisesRegex(autocal.Error, "no IMU samples"):
            autocal.write_dataset(directory, autocal.Dataset())
        n = 100
        d = autocal.Dataset()  # 200 Hz stamped in microseconds
        d.set_imu(1_000_000 + 5_000 * np.arange(n), np.zeros((n, 3)), np.tile([0, 0, 9.81], (n, 1)))
        with self.assertRaisesRegex(autocal.Error, "written, but .* microseconds"):
            autocal.write_dataset(directory, d)


class Sweeps(unittest.TestCase):
    def test_a_simulated_sweep_reads_as_arrays(self):
        directory = output_dir("urban_2s_lidar")
        tool = os.path.join(os.environ["AUTOCAL_TOOL_DIR"], "autocal_simulate")
        subprocess.run([tool, "--scenario=urban", "--duration_s=2", "--seed=2", "--lidar_beams=16",
                        "--out=" + directory], check=True, capture_output=True)
        d = autocal.read_dataset(directory)
        self.assertGreater(d.lidar_sweeps, 10)
        sweep = d.load_sweep(0)
        n = sweep["points"].shape[0]
        self.assertGreater(n, 1000)
        self.assertEqual(sweep["points"].shape, (n, 3))
        self.assertEqual(sweep["time_s"].shape, (n,))
        self.assertTrue(np.all(np.isfinite(sweep["points"])))
        with self.assertRaises(autocal.Error):
            d.load_sweep(d.lidar_sweeps)


class Preintegration(unittest.TestCase):
    # 1 s at 100 Hz: a constant turn rate about z and a constant specific force along x in
    # the turning frame; with gravity left in the deltas (Eq. F3), the closed forms are
    # delta_R = Rz(w T), delta_v = integral of Rz(w t) f dt.
    def test_matches_the_closed_form_of_a_constant_turn(self):
        w, f, T = 0.5, 2.0, 1.0
        t_ns = (np.arange(101, dtype=np.int64) * 10_000_000)
        gyro = np.tile([0.0, 0.0, w], (101, 1))
        accel = np.tile([f, 0.0, 0.0], (101, 1))
        p = autocal.preintegrate(t_ns, gyro, accel, 0, 1_000_000_000)
        self.assertAlmostEqual(p["dt_s"], T, places=12)
        np.testing.assert_allclose(p["delta_R"], rot_z(w * T), atol=1e-12)
        expected_v = f / w * np.array([math.sin(w * T), 1.0 - math.cos(w * T), 0.0])
        np.testing.assert_allclose(p["delta_v"], expected_v, atol=2e-4)
        cov = p["covariance"]
        self.assertEqual(cov.shape, (15, 15))
        np.testing.assert_allclose(cov, cov.T, atol=1e-18)
        self.assertTrue(np.all(np.linalg.eigvalsh(cov) > 0.0))


class Registration(unittest.TestCase):
    # Points on a floor and two walls; the source is the target seen from a pose moved by
    # 0.3 m and 3 degrees of yaw.
    def test_recovers_a_known_motion(self):
        rng = np.random.default_rng(7)
        u = rng.uniform(-10.0, 10.0, (3000, 2))
        floor = np.column_stack([u[:1000, 0], u[:1000, 1], np.zeros(1000)])
        wall_x = np.column_stack([np.full(1000, 8.0), u[1000:2000, 0], u[1000:2000, 1] * 0.2 + 2])
        wall_y = np.column_stack([u[2000:, 0], np.full(1000, -6.0), u[2000:, 1] * 0.2 + 2])
        target = np.vstack([floor, wall_x, wall_y])
        T = np.eye(4)
        T[:3, :3] = rot_z(math.radians(3.0))
        T[:3, 3] = [0.3, -0.1, 0.02]
        source = (target - T[:3, 3]) @ T[:3, :3]  # p_source = R^T (p_target - t)
        r = autocal.register(source, target, voxel_m=0.0, max_iterations=50)
        self.assertTrue(r["converged"])
        np.testing.assert_allclose(r["T_target_source"], T, atol=1e-6)
        self.assertEqual(r["covariance"].shape, (6, 6))
        gicp = autocal.register(source, target, voxel_m=0.0, method="gicp", max_iterations=50)
        self.assertTrue(gicp["converged"])
        np.testing.assert_allclose(gicp["T_target_source"], T, atol=1e-6)
        # From a guess next to the answer it takes fewer iterations.
        near = autocal.register(source, target, init=T, voxel_m=0.0)
        self.assertLessEqual(near["iterations"], r["iterations"])
        with self.assertRaises(autocal.Error):
            autocal.register(source, target, init=2.0 * np.eye(4))


class Pipeline(unittest.TestCase):
    # A 30 s simulated urban drive without the LiDAR, calibrated from problems/
    # imu_wheel_gnss.yaml with a progress callback, and compared with its ground truth.
    @classmethod
    def setUpClass(cls):
        cls.dataset = output_dir("urban_30s")
        tool = os.path.join(os.environ["AUTOCAL_TOOL_DIR"], "autocal_simulate")
        subprocess.run([tool, "--scenario=urban", "--duration_s=30", "--seed=5", "--lidar=false",
                        "--out=" + cls.dataset], check=True, capture_output=True)
        cls.problem = os.path.join(os.environ["AUTOCAL_SOURCE_DIR"], "problems",
                                   "imu_wheel_gnss.yaml")

    def test_calibrates_with_progress_and_meets_the_truth(self):
        stages = []
        result = autocal.calibrate(self.dataset, self.problem,
                                   progress=lambda p: stages.append((p.stage, p.fraction)))
        self.assertIn(("solving", 1.0), stages)
        truth = autocal.read_calibration(os.path.join(self.dataset, "groundtruth",
                                                      "calibration.yaml"))
        errors = autocal.compare_calibration(result.calibration.value, truth.value)
        self.assertLess(abs(errors["wheel_radius_left_percent"]), 0.05)
        self.assertLess(abs(errors["wheel_radius_right_percent"]), 0.05)
        self.assertIn("wheel_radius_left_m", result.calibration.sigma)
        trajectory = result.trajectory
        self.assertEqual(trajectory["p_W_I"].shape, (len(trajectory["t_ns"]), 3))
        out = output_dir("urban_30s_result")
        result.write(out)
        self.assertTrue(os.path.exists(os.path.join(out, "calibration.yaml")))
        # The written trajectory reads back (stamps exact, values in shortest round-trip text).
        back = autocal.read_trajectory(os.path.join(out, "trajectory.tum"))
        np.testing.assert_array_equal(back["t_ns"], trajectory["t_ns"])
        np.testing.assert_array_equal(back["p_W_I"], trajectory["p_W_I"])
        # Against the ground truth: the keyframes within 10 cm after the 4-DoF alignment.
        gt = autocal.read_dataset(self.dataset).groundtruth_trajectory
        ate = autocal.compare_trajectory(trajectory["t_ns"], trajectory["p_W_I"],
                                         trajectory["q_W_I_xyzw"], gt["t_ns"], gt["p_W_I"],
                                         gt["q_W_I_xyzw"])
        self.assertGreater(ate["matched_poses"], 100)
        self.assertLess(ate["ate_translation_rmse_m"], 0.10)
        self.assertLessEqual(ate["tilt_rmse_deg"], ate["ate_rotation_rmse_deg"] + 1e-12)

    def test_calibrates_several_logs_and_gathers_a_fleet(self):
        tool = os.path.join(os.environ["AUTOCAL_TOOL_DIR"], "autocal_simulate")
        second = output_dir("urban_30s_seed6")
        subprocess.run([tool, "--scenario=urban", "--duration_s=30", "--seed=6", "--lidar=false",
                        "--right_wheel_radius_change_pct=0.4", "--out=" + second],
                       check=True, capture_output=True)
        result = autocal.calibrate_logs([self.dataset, second], self.problem)
        self.assertEqual([log["name"] for log in result.logs], ["urban_30s", "urban_30s_seed6"])
        right = [r for r in result.repeatability if r.name == "right rear wheel radius"][0]
        self.assertFalse(right.agree)
        self.assertIn("tyre pressure or wear?", right.finding)
        self.assertLess(right.p_value, 1e-6)
        left = [r for r in result.repeatability if r.name == "left rear wheel radius"][0]
        self.assertEqual(left.degrees_of_freedom, 1)
        out = output_dir("two_logs_result")
        result.write(out)
        self.assertTrue(os.path.exists(os.path.join(out, "repeatability.csv")))
        # A fleet of one calibrated run and one that never ran.
        run_dir = os.path.join(output_dir("fleet"), "car_1")
        calibrate = os.path.join(os.environ["AUTOCAL_TOOL_DIR"], "autocal_calibrate")
        subprocess.run([calibrate, "--dataset=" + second, "--problem=" + self.problem,
                        "--vehicle=car_1", "--output=" + run_dir, "--progress=false"],
                       check=True, capture_output=True)
        report = autocal.fleet_report([run_dir, output_dir("never_ran")])
        self.assertEqual([run["vehicle"] for run in report["runs"]], ["car_1", "never_ran"])
        self.assertEqual(report["runs"][0]["failure"], "")
        self.assertIn("no status.yaml", report["runs"][1]["failure"])
        value, sigma = report["runs"][0]["values"]["wheel_radius_right_m"]
        own = result.logs[1]["own"].calibration.value.wheel_radius_right_m
        self.assertAlmostEqual(value, own, delta=3 * sigma)
        self.assertTrue(report["csv"].startswith("vehicle,directory,exit_status,message,"))

    def test_an_exception_in_the_callback_stops_the_run(self):
        def stop(progress):
            raise KeyboardInterrupt("stopped by the user")
        with self.assertRaises(KeyboardInterrupt):
            autocal.calibrate(self.dataset, self.problem, progress=stop)

    def test_streams_the_log_online(self):
        updates = []
        result = autocal.estimate_online(self.dataset, self.problem,
                                         progress=lambda p: updates.append(p.updates))
        self.assertGreater(len(updates), 0)
        self.assertGreater(len(result.trajectory["t_ns"]), 100)


if __name__ == "__main__":
    unittest.main()
