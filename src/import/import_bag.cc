// ImportBag: bag -> dataset directory, as named steps: check the output location, open the
// bag, choose the topics, stream the messages (sweeps written as they come, the small
// streams collected), then write the small streams and sensors.yaml, read the result back
// with the dataset reader and rename it into place.

#include "autocal/import/import_bag.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "autocal/common/error.h"
#include "autocal/io/dataset.h"
#include "import/bag_reader.h"
#include "import/import_from_reader.h"
#include "import/import_streams.h"
#include "import/output_directory.h"
#include "import/topic_selection.h"

namespace autocal {
namespace import {
namespace {

void Describe(const SelectedTopic& selected, ImportedStream* stream) {
  stream->topic = selected.topic;
  stream->type = selected.type;
}

// `why` without `directory`'s path: the temporary directory is removed on the way out, so
// naming it would point the user at nothing.
std::string WithoutDirectory(std::string why, const std::string& directory) {
  const std::string prefix = directory + "/";
  for (size_t at = why.find(prefix); at != std::string::npos; at = why.find(prefix)) {
    why.erase(at, prefix.size());
  }
  return why;
}

// Streams `reader` into `directory`: the sweeps as they come, then the small streams and
// sensors.yaml.
void WriteDataset(BagReader* reader, const ImportOptions& options, const TopicSelection& selection,
                  const std::string& directory, ImportSummary* summary) {
  io::DatasetWriter writer(directory);
  StreamImporter importer(options, selection, &writer, summary);
  BagMessage message;
  while (reader->Next(&message)) importer.Add(reader->path(), message);
  const std::vector<std::string> read_warnings = ReadWarnings(*reader);
  summary->warnings.insert(summary->warnings.begin(), read_warnings.begin(), read_warnings.end());
  importer.Finish(directory);
  writer.Close();
  // The writer makes lidar/ and groundtruth/ up front; an import fills groundtruth/ never.
  std::error_code error;
  std::filesystem::remove(directory + "/groundtruth", error);
  if (summary->lidar.written == 0) {
    std::filesystem::remove_all(directory + "/lidar", error);
    std::filesystem::remove(directory + "/lidar.csv", error);
  }
}

// Streams `reader` into output's temporary directory, checks and renames it.
ImportSummary ImportInto(BagReader* reader, const ImportOptions& options,
                         OutputDirectory* output_directory) {
  OutputDirectory& output = *output_directory;
  const TopicSelection selection = SelectTopics(reader->connections(), options);

  ImportSummary summary;
  summary.output = options.output;
  Describe(selection.imu, &summary.imu);
  Describe(selection.lidar, &summary.lidar);
  Describe(selection.wheel, &summary.wheel);
  Describe(selection.gnss, &summary.gnss);
  Describe(selection.odometry, &summary.odometry);
  const std::string& directory = output.temporary_path();
  try {
    WriteDataset(reader, options, selection, directory, &summary);
  } catch (const Error& e) {
    const std::string why = WithoutDirectory(e.what(), directory);
    if (why == e.what()) throw;  // the bag's file and byte, kept as they are
    throw Error(why);
  }
  // The result must read back as a dataset before it gets its name.
  try {
    io::ReadDataset(directory);
  } catch (const Error& e) {
    throw Error("the imported data fails the dataset checks, nothing was written: " +
                WithoutDirectory(e.what(), directory));
  }
  output.Commit();
  return summary;
}

}  // namespace

ImportSummary ImportBag(const ImportOptions& options) {
  if (options.input.empty()) throw Error("no input bag given");
  OutputDirectory output(options.output);  // checked before the bag is read
  const std::unique_ptr<BagReader> reader = OpenBag(options.input);
  return ImportInto(reader.get(), options, &output);
}

ImportSummary ImportFromReader(BagReader* reader, const ImportOptions& options) {
  OutputDirectory output(options.output);
  return ImportInto(reader, options, &output);
}

double TopicListing::mean_rate_hz() const {
  const double span = span_s();
  return message_count >= 2 && span > 0.0 ? static_cast<double>(message_count - 1) / span : 0.0;
}

}  // namespace import
}  // namespace autocal
