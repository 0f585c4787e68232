// Read speed of the ROS 2 containers: MCAP files written by the tests' MCAP writer (64 MiB of
// 1 KiB messages in 1 MiB chunks: uncompressed with and without chunk CRCs, lz4, zstd, and
// without chunks) and the same messages in a rosbag2 SQLite file. Bytes per second are the
// file's size over the time to open it and read every message.

#include <benchmark/benchmark.h>
#include <sqlite3.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "../test/import/mcap_writer.h"
#include "import/bag_reader.h"

namespace autocal {
namespace import {
namespace {

constexpr int kMessages = 65536;
constexpr int kPayloadFloats = 254;  // 4 + 4 + 254 * 4 = 1024 bytes per message

// A CDR float32 sequence of a noisy sine: about as compressible as recorded sensor data.
std::string Payload(int index) {
  std::string data("\x00\x01\x00\x00", 4);
  test::McapWriter::Put<uint32_t>(&data, kPayloadFloats);
  uint32_t noise = 2654435761u * static_cast<uint32_t>(index + 1);
  for (int i = 0; i < kPayloadFloats; ++i) {
    noise = noise * 1664525u + 1013904223u;
    const float value =
        std::sin(0.01f * (index * kPayloadFloats + i)) + static_cast<float>(noise >> 24) * 1e-4f;
    test::McapWriter::Put<float>(&data, value);
  }
  return data;
}

// A file in the temporary directory, removed when the program ends.
std::string BenchFile(const std::string& name) {
  struct Cleanup {
    std::vector<std::string> paths;
    ~Cleanup() {
      for (const std::string& path : paths) std::filesystem::remove(path);
    }
  };
  static Cleanup cleanup;
  cleanup.paths.push_back(
      (std::filesystem::temp_directory_path() / ("autocal_import_ros2_" + name)).string());
  return cleanup.paths.back();
}

// Writes the MCAP file for `kind` once per process.
const std::string& McapFile(const std::string& kind) {
  static std::map<std::string, std::string> paths;
  auto& path = paths[kind];
  if (!path.empty()) return path;
  test::McapWriterOptions options;
  options.chunked = kind != "unchunked";
  options.compression = (kind == "lz4" || kind == "zstd") ? kind : "";
  options.chunk_crc = kind != "uncompressed_nocrc";
  options.chunk_bytes = 1 << 20;
  test::McapWriter writer(options);
  const uint16_t schema = writer.AddSchema("sensor_msgs/msg/PointCloud2");
  const uint16_t channel = writer.AddChannel(schema, "/points");
  for (int i = 0; i < kMessages; ++i) writer.AddMessage(channel, uint64_t{1000000} * i, Payload(i));
  path = BenchFile(kind + ".mcap");
  test::WriteFile(path, writer.Finish());
  return path;
}

const std::string& SqliteFile() {
  static std::string path;
  if (!path.empty()) return path;
  path = BenchFile("bag.db3");
  std::filesystem::remove(path);
  sqlite3* db = nullptr;
  sqlite3_open(path.c_str(), &db);
  sqlite3_exec(db,
               "PRAGMA synchronous = OFF; BEGIN;"
               "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT "
               "NULL, serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
               "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, "
               "timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
               "CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
               "INSERT INTO topics VALUES(1, '/points', 'sensor_msgs/msg/PointCloud2', 'cdr', '');",
               nullptr, nullptr, nullptr);
  sqlite3_stmt* insert = nullptr;
  sqlite3_prepare_v2(db, "INSERT INTO messages(topic_id, timestamp, data) VALUES(1, ?, ?)", -1,
                     &insert, nullptr);
  for (int i = 0; i < kMessages; ++i) {
    const std::string data = Payload(i);
    sqlite3_bind_int64(insert, 1, int64_t{1000000} * i);
    sqlite3_bind_blob(insert, 2, data.data(), static_cast<int>(data.size()), SQLITE_TRANSIENT);
    sqlite3_step(insert);
    sqlite3_reset(insert);
  }
  sqlite3_finalize(insert);
  sqlite3_exec(db, "COMMIT;", nullptr, nullptr, nullptr);
  sqlite3_close(db);
  return path;
}

void ReadEverything(benchmark::State& state, const std::string& path,
                    std::unique_ptr<BagReader> (*open)(const std::string&)) {
  const auto file_bytes = static_cast<int64_t>(std::filesystem::file_size(path));
  for (auto _ : state) {
    const auto reader = open(path);
    BagMessage message;
    uint64_t count = 0;
    uint64_t payload_bytes = 0;
    while (reader->Next(&message)) {
      ++count;
      payload_bytes += message.data.size();
    }
    if (count != kMessages) state.SkipWithError("wrong message count");
    benchmark::DoNotOptimize(payload_bytes);
  }
  state.SetBytesProcessed(state.iterations() * file_bytes);
  state.counters["file_MB"] = static_cast<double>(file_bytes) / 1e6;
}

void BM_ReadMcap(benchmark::State& state, const char* kind) {
  ReadEverything(state, McapFile(kind), OpenMcap);
}
BENCHMARK_CAPTURE(BM_ReadMcap, uncompressed, "uncompressed")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ReadMcap, uncompressed_nocrc, "uncompressed_nocrc")
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ReadMcap, unchunked, "unchunked")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ReadMcap, lz4, "lz4")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ReadMcap, zstd, "zstd")->Unit(benchmark::kMillisecond);

void BM_ReadRosbag2Sqlite(benchmark::State& state) {
  ReadEverything(state, SqliteFile(), OpenRosbag2Sqlite);
}
BENCHMARK(BM_ReadRosbag2Sqlite)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace import
}  // namespace autocal

BENCHMARK_MAIN();
