// Reading speed of ROS 1 bags (docs/import.md, "Speed"): MB of bag file per second for
//   BM_ReadRos1Bag/<compression>   the container alone: every message's bytes, in order
//   BM_DecodeRos1Bag/<compression> the same plus decoding every PointCloud2 and Imu
//   BM_ImportRos1Bag               the whole import into a dataset directory
// on a synthetic bag (LiDAR sweeps of 28800 points with per-point time, IMU at 200 Hz)
// written by the test writer into a temporary directory.

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "../test/import/ros1_bag_writer.h"
#include "../test/import/ros_message_writer.h"
#include "autocal/import/import_bag.h"
#include "import/bag_reader.h"
#include "import/ros_messages.h"

namespace {

namespace fs = std::filesystem;
using autocal::test::Ros1BagWriter;

constexpr int64_t kStartNs = 1700000000000000000;

std::string Cloud(int64_t stamp_ns, std::mt19937* random) {
  const std::vector<autocal::test::TestPointField> fields = {
      {"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}, {"intensity", 12, 7}, {"t", 16, 6}};
  std::uniform_real_distribution<float> coordinate(-50.0f, 50.0f);
  std::string data;
  const int points = 28800;
  data.reserve(points * 20);
  for (int i = 0; i < points; ++i) {
    autocal::test::AppendValue<float>(&data, coordinate(*random));
    autocal::test::AppendValue<float>(&data, coordinate(*random));
    autocal::test::AppendValue<float>(&data, 0.1f * coordinate(*random));
    autocal::test::AppendValue<float>(&data, static_cast<float>(i % 256));
    autocal::test::AppendValue<uint32_t>(&data, static_cast<uint32_t>(i) * 3472u);
  }
  return autocal::test::SerializePointCloud2(false, stamp_ns, "lidar", 1, points, fields, 20,
                                             20 * points, data);
}

// `seconds` of a rig: sweeps at 10 Hz, IMU at 200 Hz. Cached per compression.
const std::string& BagPath(Ros1BagWriter::Compression compression, int seconds) {
  static std::map<std::pair<int, int>, std::string> paths;
  auto& path = paths[{static_cast<int>(compression), seconds}];
  if (!path.empty()) return path;
  const fs::path dir =
      fs::temp_directory_path() / ("autocal_import_bench_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const char* names[] = {"none", "bz2", "lz4"};
  path = (dir / (std::string(names[static_cast<int>(compression)]) + ".bag")).string();
  Ros1BagWriter::Options options;
  options.compression = compression;
  options.chunk_bytes = 768 * 1024;
  Ros1BagWriter writer(options);
  const uint32_t lidar = writer.AddConnection("/points", "sensor_msgs/PointCloud2");
  const uint32_t imu = writer.AddConnection("/imu", "sensor_msgs/Imu");
  std::mt19937 random(1);
  for (int i = 0; i < seconds * 200; ++i) {
    const int64_t t = kStartNs + i * 5000000LL;
    writer.Write(imu, t,
                 autocal::test::SerializeImu(false, t, "imu", {0.01, 0.02, 0.03}, {0, 0, 9.8}));
    if (i % 20 == 0) writer.Write(lidar, t, Cloud(t, &random));
  }
  Ros1BagWriter::WriteFile(path, writer.Finish());
  return path;
}

void ReadBag(benchmark::State& state, Ros1BagWriter::Compression compression, bool decode) {
  const std::string& path =
      BagPath(compression, compression == Ros1BagWriter::Compression::kBz2 ? 3 : 10);
  const int64_t bytes = static_cast<int64_t>(fs::file_size(path));
  autocal::import::MessageContext context;
  for (auto _ : state) {
    const auto reader = autocal::import::OpenBag(path);
    autocal::import::BagMessage message;
    int64_t points = 0;
    while (reader->Next(&message)) {
      benchmark::DoNotOptimize(message.data.data());
      if (!decode) continue;
      autocal::import::MessageCursor cursor(message.data, autocal::import::Serialization::kRos1,
                                            &context);
      if (message.connection_id == 0) {
        points += autocal::import::DecodePointCloud2(&cursor).cloud.size();
      } else {
        benchmark::DoNotOptimize(autocal::import::DecodeImu(&cursor));
      }
    }
    benchmark::DoNotOptimize(points);
  }
  state.SetBytesProcessed(state.iterations() * bytes);
  state.counters["bag_MB"] = static_cast<double>(bytes) / 1e6;
}

void BM_ReadRos1Bag(benchmark::State& state) {
  ReadBag(state, static_cast<Ros1BagWriter::Compression>(state.range(0)), false);
}
void BM_DecodeRos1Bag(benchmark::State& state) {
  ReadBag(state, static_cast<Ros1BagWriter::Compression>(state.range(0)), true);
}
// 0 none, 1 bz2, 2 lz4
BENCHMARK(BM_ReadRos1Bag)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DecodeRos1Bag)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_ImportRos1Bag(benchmark::State& state) {
  const std::string& path = BagPath(Ros1BagWriter::Compression::kNone, 10);
  const int64_t bytes = static_cast<int64_t>(fs::file_size(path));
  const fs::path out = fs::path(path).parent_path() / "dataset";
  for (auto _ : state) {
    state.PauseTiming();
    fs::remove_all(out);
    state.ResumeTiming();
    autocal::import::ImportOptions options;
    options.input = path;
    options.output = out.string();
    benchmark::DoNotOptimize(autocal::import::ImportBag(options));
  }
  state.SetBytesProcessed(state.iterations() * bytes);
}
BENCHMARK(BM_ImportRos1Bag)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code error;
  fs::remove_all(fs::temp_directory_path() / ("autocal_import_bench_" + std::to_string(::getpid())),
                 error);
  return 0;
}
