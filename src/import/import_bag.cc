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

  {
    io::DatasetWriter writer(output.temporary_path());
    StreamImporter importer(options, selection, &writer, &summary);
    BagMessage message;
    while (reader->Next(&message)) importer.Add(reader->path(), message);
    const std::vector<std::string> read_warnings = ReadWarnings(*reader);
    summary.warnings.insert(summary.warnings.begin(), read_warnings.begin(), read_warnings.end());
    importer.Finish(output.temporary_path());
    writer.Close();
  }
  // The writer makes lidar/ and groundtruth/ up front; an import fills groundtruth/ never.
  std::error_code error;
  std::filesystem::remove(output.temporary_path() + "/groundtruth", error);
  if (summary.lidar.written == 0)
    std::filesystem::remove(output.temporary_path() + "/lidar", error);
  // The result must read back as a dataset before it gets its name.
  try {
    io::ReadDataset(output.temporary_path());
  } catch (const Error& e) {
    std::string why = e.what();
    const std::string temporary = output.temporary_path() + "/";
    for (size_t at = why.find(temporary); at != std::string::npos; at = why.find(temporary)) {
      why.erase(at, temporary.size());
    }
    throw Error("the imported data fails the dataset checks, nothing was written: " + why);
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
