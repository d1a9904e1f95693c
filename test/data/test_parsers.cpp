// Parsers on small fixture files: good input (plain, gzip, CRLF, comments, blank lines) and each
// kind of bad input, with the error's file, line and message checked.

#include <gtest/gtest.h>

#include <cmath>

#include "core/data/parsers.h"
#include "core/data/text_file.h"
#include "data_test_utils.h"

namespace marglab {
namespace {

using test::expectInputError;
using test::TempDir;
using test::writeFile;
using test::writeGz;

const char* const kTum =
    "# timestamp(s) tx ty tz qx qy qz qw\n"
    "1403636580.83856 4.688319 -1.786938 0.783338 -0.153029 -0.827383 -0.082152 0.534108\n"
    "\n"
    "1403636580.84356 4.688177 -1.786770 0.787350 -0.152990 -0.826976 -0.082863 0.534640\n"
    "1403636580.84856 4.688028 -1.786598 0.791382 -0.152945 -0.826562 -0.083605 0.535178\n";

TEST(TumTrajectory, ReadsExactNanosecondsAndXyzwOrder) {
  TempDir dir;
  const Trajectory traj = readTumTrajectory(writeFile(dir.file("gt.txt"), kTum));
  ASSERT_EQ(traj.size(), 3u);
  EXPECT_EQ(traj.t_ns[0], 1403636580838560000);
  EXPECT_EQ(traj.t_ns[2], 1403636580848560000);
  EXPECT_EQ(traj.p_w_b[1], Eigen::Vector3d(4.688177, -1.786770, 0.787350));
  // Stored normalized; the w of the file is the last column.
  const Eigen::Quaterniond q(0.534108, -0.153029, -0.827383, -0.082152);
  EXPECT_NEAR(traj.q_w_b[0].w(), q.normalized().w(), 1e-15);
  EXPECT_NEAR(traj.q_w_b[0].x(), q.normalized().x(), 1e-15);
  EXPECT_NEAR(traj.q_w_b[0].norm(), 1.0, 1e-15);
}

TEST(TumTrajectory, GzipAndCrlfGiveTheSameResult) {
  TempDir dir;
  std::string crlf;
  for (const char* c = kTum; *c != '\0'; ++c)
    crlf += *c == '\n' ? std::string("\r\n") : std::string(1, *c);
  const Trajectory plain = readTumTrajectory(writeFile(dir.file("a.txt"), kTum));
  const Trajectory gz = readTumTrajectory(writeGz(dir.file("b.txt.gz"), crlf));
  ASSERT_EQ(gz.size(), plain.size());
  for (std::size_t i = 0; i < plain.size(); ++i) {
    EXPECT_EQ(gz.t_ns[i], plain.t_ns[i]);
    EXPECT_EQ(gz.p_w_b[i], plain.p_w_b[i]);
    EXPECT_EQ(gz.q_w_b[i].coeffs(), plain.q_w_b[i].coeffs());
  }
}

TEST(TumTrajectory, BadInputNamesFileAndLine) {
  TempDir dir;
  const std::string head = "# header\n1.0 0 0 0 0 0 0 1\n";
  const auto bad = [&](const std::string& name, const std::string& row, int line,
                       const std::string& fragment) {
    const std::string path = writeFile(dir.file(name), head + row);
    expectInputError([&] { readTumTrajectory(path); }, path, line, fragment);
  };
  bad("columns.txt", "2.0 0 0 0 0 0 1\n", 3, "expected 8 columns");
  bad("letters.txt", "2.0 0 0x 0 0 0 0 1\n", 3, "expected a number in column 3 (y), found '0x'");
  bad("nan.txt", "2.0 0 0 nan 0 0 0 1\n", 3, "expected a finite number in column 4 (z)");
  bad("inf.txt", "2.0 0 0 0 0 0 0 inf\n", 3, "expected a finite number in column 8 (qw)");
  bad("backwards.txt", "0.5 0 0 0 0 0 0 1\n", 3, "expected timestamps increasing strictly");
  bad("duplicate.txt", "\n1.0 0 0 0 0 0 0 1\n", 4, "expected timestamps increasing strictly");
  bad("quaternion.txt", "2.0 0 0 0 0 0 0 0.9\n", 3, "expected a unit quaternion");
  bad("time.txt", "2.0s 0 0 0 0 0 0 1\n", 3, "expected a number in column 1 (t [s])");

  const std::string empty = writeFile(dir.file("empty.txt"), "# only a header\n\n");
  expectInputError([&] { readTumTrajectory(empty); }, empty, 2, "expected at least one pose");
  const std::string missing = dir.file("missing.txt");
  expectInputError([&] { readTumTrajectory(missing); }, missing, 0, "expected an existing file");
}

TEST(TextFile, TruncatedGzipIsAnError) {
  TempDir dir;
  std::string text;
  for (int i = 0; i < 20000; ++i) text += std::to_string(1000 + i) + " 0 0 0 0 0 0 1\n";
  const std::string path = writeGz(dir.file("t.txt.gz"), text);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  EXPECT_THROW(readTumTrajectory(path), InputError);
}

TEST(TextFile, SecondsToNanoseconds) {
  TempDir dir;
  const std::string path = writeFile(dir.file("t.txt"), "x\n");
  TextFile file(path);
  EXPECT_EQ(parseSecondsToNs("1520531829.301144123", file, "t"), 1520531829301144123);
  EXPECT_EQ(parseSecondsToNs("1520531829.3011441239", file, "t"), 1520531829301144124);
  EXPECT_EQ(parseSecondsToNs("12", file, "t"), 12000000000);
  EXPECT_EQ(parseSecondsToNs("1.037359e-01", file, "t"), 103735900);
  EXPECT_EQ(parseSecondsToNs("4.705816e+02", file, "t"), 470581600000);
  EXPECT_THROW(parseSecondsToNs("1.2.3", file, "t"), InputError);
  EXPECT_THROW(parseSecondsToNs("", file, "t"), InputError);
}

TEST(AslGroundTruth, EurocSeventeenColumnsWithBiases) {
  TempDir dir;
  const std::string path = writeFile(
      dir.file("data.csv"),
      "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
      "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
      "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
      "b_a_RS_S_z [m s^-2]\n"
      "1403638128940097024,4.677066,-1.749440,0.568567,0.240749,-0.761130,-0.355916,-0.485843,"
      "0.002118,-0.005923,-0.002323,-0.002133,0.021059,0.076659,-0.026895,0.136910,0.059287\n"
      "1403638128945096960,4.677072,-1.749469,0.568555,0.240790,-0.761103,-0.355913,-0.485868,"
      "0.000566,-0.005685,-0.002679,-0.002133,0.021059,0.076659,-0.026895,0.136910,0.059287\n");
  const AslGroundTruth gt = readAslGroundTruth(path);
  ASSERT_EQ(gt.trajectory.size(), 2u);
  EXPECT_EQ(gt.trajectory.t_ns[1], 1403638128945096960);
  EXPECT_NEAR(gt.trajectory.q_w_b[0].w(), 0.240749, 1e-6);  // w first in ASL
  EXPECT_NEAR(gt.trajectory.q_w_b[0].z(), -0.485843, 1e-6);
  ASSERT_TRUE(gt.state.has_value());
  EXPECT_EQ(gt.state->v_w_b[1], Eigen::Vector3d(0.000566, -0.005685, -0.002679));
  EXPECT_EQ(gt.state->bias_gyro[0], Eigen::Vector3d(-0.002133, 0.021059, 0.076659));
  EXPECT_EQ(gt.state->bias_accel[0], Eigen::Vector3d(-0.026895, 0.136910, 0.059287));
}

TEST(AslGroundTruth, TumviEightColumnsAndBadRows) {
  TempDir dir;
  const std::string good =
      "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
      "q_RS_z []\n"
      "1520530308189679351,0.8417820384,-0.2193354118,1.2499749141,0.9996498117,0.0037373093,"
      "0.0097169635,-0.0243283190\n";
  const AslGroundTruth gt = readAslGroundTruth(writeFile(dir.file("ok.csv"), good));
  ASSERT_EQ(gt.trajectory.size(), 1u);
  EXPECT_FALSE(gt.state.has_value());
  EXPECT_EQ(gt.trajectory.t_ns[0], 1520530308189679351);

  const std::string short_row =
      writeFile(dir.file("short.csv"), good + "1520530308198012351,1,2\n");
  expectInputError([&] { readAslGroundTruth(short_row); }, short_row, 3, "expected 8 columns");
  const std::string nine = writeFile(dir.file("nine.csv"), "1,0,0,0,1,0,0,0,5\n");
  expectInputError([&] { readAslGroundTruth(nine); }, nine, 1, "expected 8 columns");
  const std::string float_time = writeFile(dir.file("ft.csv"), good + "1.5e18,0,0,0,1,0,0,0\n");
  expectInputError([&] { readAslGroundTruth(float_time); }, float_time, 3,
                   "expected an integer in column 1 (t [ns])");
}

TEST(AslImu, CrlfRowsAndBadInput) {
  TempDir dir;
  const std::string header =
      "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m "
      "s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\r\n";
  const std::string rows =
      "1403638127270096896,-0.010471975511965976,0.01117010721276371,0.065624379874986788,"
      "8.9567403333333324,0.081722083333333334,-3.9308322083333329\r\n"
      "1403638127275097088,-0.012566370614359173,0.0153588974175501,0.059341194567807204,"
      "9.0956678750000002,0.04903325,-3.947176625\r\n";
  const ImuData imu = readAslImu(writeFile(dir.file("imu.csv"), header + rows));
  ASSERT_EQ(imu.size(), 2u);
  EXPECT_EQ(imu.t_ns[0], 1403638127270096896);
  EXPECT_DOUBLE_EQ(imu.gyro[0].x(), -0.010471975511965976);
  EXPECT_DOUBLE_EQ(imu.accel[1].z(), -3.947176625);

  const std::string letters = writeFile(
      dir.file("letters.csv"), header + rows + "1403638127280097024,0,0,0,9.1,0.04,abc\r\n");
  expectInputError([&] { readAslImu(letters); }, letters, 4,
                   "expected a number in column 7 (a_z), found 'abc'");
  const std::string back =
      writeFile(dir.file("back.csv"), header + rows + "1403638127270096896,0,0,0,9.1,0.04,1\r\n");
  expectInputError([&] { readAslImu(back); }, back, 4, "expected timestamps increasing strictly");
  const std::string empty_field =
      writeFile(dir.file("empty_field.csv"), header + "1403638127270096896,0,,0,9.1,0.04,1\r\n");
  expectInputError([&] { readAslImu(empty_field); }, empty_field, 2,
                   "expected a number in column 3 (w_y), found ''");
}

TEST(TimestampList, PlainAndAslCameraCsv) {
  TempDir dir;
  const auto plain =
      readTimestampList(writeFile(dir.file("t.txt"), "1403636579763555584\n1403636579813555456\n"));
  EXPECT_EQ(plain, (std::vector<int64_t>{1403636579763555584, 1403636579813555456}));
  const auto asl = readTimestampList(
      writeFile(dir.file("data.csv"),
                "#timestamp [ns],filename\r\n1403636579763555584,1403636579763555584.png\r\n"
                "1403636579813555456,1403636579813555456.png\r\n"));
  EXPECT_EQ(asl, plain);
  const std::string three = writeFile(dir.file("three.csv"), "1,a.png\n2,b.png,x\n");
  expectInputError([&] { readTimestampList(three); }, three, 2, "found 3 columns");
  const std::string back = writeFile(dir.file("back.txt"), "5\n6\n4\n");
  expectInputError([&] { readTimestampList(back); }, back, 3, "found 4 after 6");
}

const char* const kSensorYaml = R"(# General sensor definitions.
sensor_type: camera
comment: VI-Sensor cam0 (MT9M034)

# Sensor extrinsics wrt. the body-frame.
T_BS:
  cols: 4
  rows: 4
  data: [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,
         0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768,
        -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,
         0.0, 0.0, 0.0, 1.0]

# Camera specific definitions.
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05])";

TEST(EurocSensorYaml, IntrinsicsExtrinsicsDistortion) {
  TempDir dir;
  const CameraCalib cam = readEurocSensorYaml(writeFile(dir.file("sensor.yaml"), kSensorYaml));
  EXPECT_EQ(cam.fx, 458.654);
  EXPECT_EQ(cam.fy, 457.296);
  EXPECT_EQ(cam.cx, 367.215);
  EXPECT_EQ(cam.cy, 248.375);
  EXPECT_EQ(cam.width, 752);
  EXPECT_EQ(cam.height, 480);
  EXPECT_EQ(cam.distortion_model, "radtan");
  ASSERT_EQ(cam.distortion.size(), 4u);
  EXPECT_EQ(cam.distortion[3], 1.76187114e-05);
  EXPECT_EQ(cam.t_b_c, Eigen::Vector3d(-0.0216401454975, -0.064676986768, 0.00981073058949));
  EXPECT_NEAR(cam.R_b_c(1, 0), 0.999557249008, 1e-9);
  EXPECT_NEAR((cam.R_b_c.transpose() * cam.R_b_c - Eigen::Matrix3d::Identity()).norm(), 0, 1e-14);
}

TEST(EurocSensorYaml, BadInput) {
  TempDir dir;
  std::string yaml = kSensorYaml;
  const std::string no_res =
      writeFile(dir.file("nores.yaml"), yaml.replace(yaml.find("resolution"), 10, "resolutio_"));
  expectInputError([&] { readEurocSensorYaml(no_res); }, no_res, 0,
                   "expected the key 'resolution'");
  yaml = kSensorYaml;
  const std::string bad_number =
      writeFile(dir.file("badnum.yaml"), yaml.replace(yaml.find("458.654"), 7, "458.6x4"));
  expectInputError([&] { readEurocSensorYaml(bad_number); }, bad_number, 18,
                   "expected finite numbers in 'intrinsics', found '458.6x4'");
  yaml = kSensorYaml;
  const std::string not_rigid =
      writeFile(dir.file("rigid.yaml"), yaml.replace(yaml.find("0.999557249008"), 14, "0.5"));
  expectInputError([&] { readEurocSensorYaml(not_rigid); }, not_rigid, 9,
                   "expected a rigid transform in 'T_BS.data'");
  for (const char* resolution : {"[752, 1e300]", "[752.5, 480]", "[0, 480]", "[752, 65537]"}) {
    yaml = kSensorYaml;
    const std::string bad_size =
        writeFile(dir.file("size.yaml"), yaml.replace(yaml.find("[752, 480]"), 10, resolution));
    expectInputError([&] { readEurocSensorYaml(bad_size); }, bad_size, 16,
                     "expected a resolution of whole numbers in [1, 65536]");
  }
}

TEST(KalibrCamchain, TCamImuIsInvertedToTBodyCamera) {
  TempDir dir;
  // R_c_b = rotation of +90° about z, t_c_b = (1, 2, 3).
  const std::string chain = R"(%YAML:1.0 # comment
cam0:
  T_cam_imu: #rotation from IMU to camera
    - [0.0, -1.0, 0.0, 1.0]
    - [1.0, 0.0, 0.0, 2.0]
    - [0.0, 0.0, 1.0, 3.0]
    - [0.0, 0.0, 0.0, 1.0]
  distortion_coeffs: [0.1, 0.2, 0.3, 0.4]
  distortion_model: equidistant
  intrinsics: [190.0, 191.0, 254.0, 256.0]
  resolution: [512, 512]
cam1:
  T_imu_cam:
    - [1.0, 0.0, 0.0, 0.5]
    - [0.0, 1.0, 0.0, 0.0]
    - [0.0, 0.0, 1.0, 0.0]
    - [0.0, 0.0, 0.0, 1.0]
  intrinsics: [180.0, 181.0, 250.0, 251.0]
  resolution: [512, 512]
)";
  const StereoCalib stereo = readKalibrCamchain(writeFile(dir.file("chain.yaml"), chain));
  Eigen::Matrix3d R_c_b;
  R_c_b << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_NEAR((stereo.cam0.R_b_c - R_c_b.transpose()).norm(), 0, 1e-15);
  EXPECT_NEAR((stereo.cam0.t_b_c - (-R_c_b.transpose() * Eigen::Vector3d(1, 2, 3))).norm(), 0,
              1e-15);
  EXPECT_EQ(stereo.cam0.distortion_model, "equidistant");
  EXPECT_EQ(stereo.cam0.distortion.size(), 4u);
  EXPECT_EQ(stereo.cam0.fy, 191.0);
  EXPECT_EQ(stereo.cam1.t_b_c, Eigen::Vector3d(0.5, 0, 0));
  EXPECT_EQ(stereo.cam1.cx, 250.0);
  EXPECT_EQ(stereo.cam1.distortion_model, "none");
}

TEST(KalibrImuNoise, NestedAndTopLevelKeys) {
  TempDir dir;
  const ImuNoise nested = readKalibrImuNoise(writeFile(dir.file("chain.yaml"), R"(%YAML:1.0
imu0:
  T_i_b:
    - [1.0, 0.0, 0.0, 0.0]
  accelerometer_noise_density: 2.0000e-3  # [ m / s^2 / sqrt(Hz) ]
  accelerometer_random_walk: 3.0000e-3
  gyroscope_noise_density: 1.6968e-04
  gyroscope_random_walk: 1.9393e-05
  model: "kalibr"
)"));
  EXPECT_EQ(nested.gyro_noise_density, 1.6968e-4);
  EXPECT_EQ(nested.gyro_random_walk, 1.9393e-5);
  EXPECT_EQ(nested.accel_noise_density, 2.0e-3);
  EXPECT_EQ(nested.accel_random_walk, 3.0e-3);
  const ImuNoise top = readKalibrImuNoise(writeFile(dir.file("imu.yaml"),
                                                    "gyroscope_noise_density: 1.6e-4\n"
                                                    "gyroscope_random_walk: 2.2e-5\n"
                                                    "accelerometer_noise_density: 2.8e-3\n"
                                                    "accelerometer_random_walk: 8.6e-4\n"));
  EXPECT_EQ(top.accel_random_walk, 8.6e-4);
  const std::string negative = writeFile(dir.file("neg.yaml"),
                                         "gyroscope_noise_density: -1.6e-4\n"
                                         "gyroscope_random_walk: 2.2e-5\n"
                                         "accelerometer_noise_density: 2.8e-3\n"
                                         "accelerometer_random_walk: 8.6e-4\n");
  expectInputError([&] { readKalibrImuNoise(negative); }, negative, 1,
                   "expected 'gyroscope_noise_density' > 0");
}

const char* const kKittiCalib =
    "P0: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 0.000000000000e+00 "
    "0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 "
    "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00\n"
    "P1: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 -3.861448000000e+02 "
    "0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 "
    "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00\n";

TEST(Kitti, CalibBaselineFromP1) {
  TempDir dir;
  const StereoCalib stereo = readKittiCalib(writeFile(dir.file("calib.txt"), kKittiCalib));
  EXPECT_EQ(stereo.cam0.fx, 718.856);
  EXPECT_EQ(stereo.cam0.cx, 607.1928);
  EXPECT_EQ(stereo.cam0.cy, 185.2157);
  EXPECT_EQ(stereo.cam0.width, 1241);
  EXPECT_EQ(stereo.cam0.height, 376);
  EXPECT_EQ(stereo.cam0.t_b_c, Eigen::Vector3d::Zero());
  EXPECT_DOUBLE_EQ(stereo.cam1.t_b_c.x(), 386.1448 / 718.856);
  EXPECT_NEAR(stereo.baseline(), 0.5372, 1e-4);

  const std::string only_p0 = writeFile(
      dir.file("p0.txt"), std::string(kKittiCalib).substr(0, std::string(kKittiCalib).find("P1")));
  expectInputError([&] { readKittiCalib(only_p0); }, only_p0, 0, "expected a line 'P1:'");
  const std::string short_p1 =
      writeFile(dir.file("short.txt"), std::string(kKittiCalib) + "P2: 1 2 3\n");
  expectInputError([&] { readKittiCalib(short_p1); }, short_p1, 3, "expected 13 columns");
}

TEST(Kitti, TimesAndPoses) {
  TempDir dir;
  const auto t_ns = readKittiTimes(
      writeFile(dir.file("times.txt"), "0.000000e+00\n1.037359e-01\n2.073381e-01\n"));
  EXPECT_EQ(t_ns, (std::vector<int64_t>{0, 103735900, 207338100}));
  const std::string rows =
      "1.000000e+00 9.043680e-12 2.326809e-11 5.551115e-17 9.043683e-12 1.000000e+00 "
      "2.392370e-10 3.330669e-16 2.326810e-11 2.392370e-10 9.999999e-01 -4.440892e-16\n"
      "9.999978e-01 5.272628e-04 -2.066935e-03 -4.690294e-02 -5.296506e-04 9.999992e-01 "
      "-1.154865e-03 -2.839928e-02 2.066324e-03 1.155958e-03 9.999971e-01 8.586941e-01\n";
  const std::string third =
      "9.999910e-01 1.048972e-03 -4.131348e-03 -9.374345e-02 -1.058514e-03 9.999968e-01 "
      "-2.308104e-03 -5.676064e-02 4.128913e-03 2.312456e-03 9.999887e-01 1.716275e+00\n";
  const Trajectory traj = readKittiPoses(writeFile(dir.file("poses.txt"), rows + third), t_ns);
  ASSERT_EQ(traj.size(), 3u);
  EXPECT_EQ(traj.t_ns[1], 103735900);
  EXPECT_EQ(traj.p_w_b[2], Eigen::Vector3d(-9.374345e-02, -5.676064e-02, 1.716275e+00));
  EXPECT_NEAR(traj.q_w_b[1].toRotationMatrix()(0, 2), -2.066935e-03, 1e-6);

  const std::string too_few = writeFile(dir.file("few.txt"), rows);
  expectInputError([&] { readKittiPoses(too_few, t_ns); }, too_few, 2, "expected 3 poses");
  const std::string too_many = writeFile(dir.file("many.txt"), rows + third + third);
  expectInputError([&] { readKittiPoses(too_many, t_ns); }, too_many, 4, "this is one more");
  const std::string not_rotation =
      writeFile(dir.file("rot.txt"), rows + "2 0 0 0 0 1 0 0 0 0 1 0\n");
  expectInputError([&] { readKittiPoses(not_rotation, t_ns); }, not_rotation, 3,
                   "expected a rotation");
  const std::string eleven = writeFile(dir.file("eleven.txt"), rows + "1 0 0 0 0 1 0 0 0 0 1\n");
  expectInputError([&] { readKittiPoses(eleven, t_ns); }, eleven, 3, "expected 12 columns");
  const std::string back = writeFile(dir.file("back.txt"), "0.1\n0.2\n0.15\n");
  expectInputError([&] { readKittiTimes(back); }, back, 3, "expected timestamps increasing");
}

}  // namespace
}  // namespace marglab
