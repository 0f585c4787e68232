// MCAP (mcap.dev/spec) as a BagReader. Open reads the magic, the header, the footer and,
// when present, the summary section (schemas, channels, statistics, chunk indexes); Next
// walks the data section in file order. A file without summary channels is scanned once at
// open for its Schema and Channel records.

#include <cstring>
#include <memory>
#include <unordered_map>
#include <vector>

#include "autocal/common/error.h"
#include "import/bag_reader.h"
#include "import/crc32.h"
#include "import/mcap_data_walker.h"
#include "import/mcap_format.h"
#include "import/mcap_mapped_file.h"
#include "import/mcap_summary.h"

namespace autocal {
namespace import {
namespace {

using internal::Hex;
using internal::kMcapFooterContentBytes;
using internal::kMcapMagic;
using internal::kMcapRecordPrefixBytes;
using internal::McapDataWalker;
using internal::McapFields;
using internal::McapPlace;
using internal::McapRecord;
using internal::McapSummary;

constexpr uint64_t kFooterRecordBytes = kMcapRecordPrefixBytes + kMcapFooterContentBytes;

class McapReader final : public BagReader {
 public:
  explicit McapReader(const std::string& path);

  const std::string& path() const override { return path_; }
  const std::vector<Connection>& connections() const override { return connections_; }
  std::optional<std::vector<IndexedTopic>> IndexedTopics() const override { return indexed_; }
  bool Next(BagMessage* message) override;

 private:
  void ReadHeader();
  void ReadFooter();
  void CheckSummaryCrc(uint32_t summary_crc) const;
  void ScanChannels();
  uint32_t DataEndCrc() const;

  std::string path_;
  internal::MappedFile file_;
  std::string_view bytes_;
  McapPlace place_;
  uint64_t data_begin_ = 0;  // the first record after the header
  uint64_t data_limit_ = 0;  // where the data section ends at the latest
  uint64_t summary_start_ = 0;
  uint64_t summary_offset_start_ = 0;
  uint64_t footer_offset_ = 0;

  internal::McapChannels channels_;
  std::vector<Connection> connections_;
  std::optional<std::vector<IndexedTopic>> indexed_;

  std::unique_ptr<McapDataWalker> walker_;
  // Channels defined by a Channel record met so far in the data section (the spec requires
  // one before the channel's first message).
  std::vector<bool> defined_in_data_;
};

McapReader::McapReader(const std::string& path)
    : path_(path), file_(path), bytes_(file_.bytes()), place_{&path_} {
  ReadHeader();
  ReadFooter();
  McapSummary summary(path_, bytes_, summary_start_,
                      summary_offset_start_ != 0 ? summary_offset_start_ : footer_offset_);
  channels_ = summary.channels();
  if (!channels_.HasChannels()) ScanChannels();
  connections_ = channels_.Connections();
  indexed_ = summary.IndexedTopics(connections_);
  walker_ = std::make_unique<McapDataWalker>(path_, bytes_, data_begin_, data_limit_, DataEndCrc());
  defined_in_data_.assign(65536, false);
}

// The leading magic and the Header record: data_begin_.
void McapReader::ReadHeader() {
  const uint64_t size = bytes_.size();
  if (size < kMcapMagic.size() || bytes_.substr(0, kMcapMagic.size()) != kMcapMagic) {
    throw ParseError({path_, 0, 0, 0},
                     "not an MCAP file: it does not start with the MCAP magic \\x89MCAP0\\r\\n");
  }
  const uint64_t header_offset = kMcapMagic.size();
  if (size - header_offset < kMcapRecordPrefixBytes ||
      static_cast<uint8_t>(bytes_[header_offset]) != internal::kOpHeader) {
    place_.Fail(header_offset, internal::kOpHeader,
                "expected right after the magic (truncated file or not MCAP)");
  }
  uint64_t header_length;
  std::memcpy(&header_length, bytes_.data() + header_offset + 1, 8);
  if (header_length > size - header_offset - kMcapRecordPrefixBytes) {
    place_.Fail(header_offset, internal::kOpHeader,
                "its length " + std::to_string(header_length) +
                    " runs past the end of the file (truncated file)");
  }
  McapFields header(bytes_.substr(header_offset + kMcapRecordPrefixBytes, header_length),
                    header_offset + kMcapRecordPrefixBytes, internal::kOpHeader, place_);
  header.Prefixed32("profile");
  header.Prefixed32("library");
  data_begin_ = header_offset + kMcapRecordPrefixBytes + header_length;
}

// The Footer record and the trailing magic: where the summary and the data section end.
void McapReader::ReadFooter() {
  const uint64_t size = bytes_.size();
  if (size - data_begin_ < kFooterRecordBytes + kMcapMagic.size() ||
      bytes_.substr(size - kMcapMagic.size()) != kMcapMagic) {
    throw ParseError({path_, 0, 0, static_cast<int64_t>(size)},
                     "the file does not end with a Footer record and the MCAP magic: it is "
                     "truncated (an interrupted recording?) or not an MCAP file");
  }
  footer_offset_ = size - kMcapMagic.size() - kFooterRecordBytes;
  uint64_t footer_length;
  std::memcpy(&footer_length, bytes_.data() + footer_offset_ + 1, 8);
  if (static_cast<uint8_t>(bytes_[footer_offset_]) != internal::kOpFooter ||
      footer_length != kMcapFooterContentBytes) {
    place_.Fail(footer_offset_, internal::kOpFooter,
                "expected a 20-byte Footer record before the trailing magic");
  }
  McapFields footer(bytes_.substr(footer_offset_ + kMcapRecordPrefixBytes, footer_length),
                    footer_offset_ + kMcapRecordPrefixBytes, internal::kOpFooter, place_);
  summary_start_ = footer.U64("summary_start");
  summary_offset_start_ = footer.U64("summary_offset_start");
  const uint32_t summary_crc = footer.U32("summary_crc");

  const auto in_range = [&](uint64_t offset, uint64_t lowest) {
    return offset == 0 || (offset >= lowest && offset <= footer_offset_);
  };
  if (!in_range(summary_start_, data_begin_) ||
      !in_range(summary_offset_start_, summary_start_ != 0 ? summary_start_ : data_begin_)) {
    place_.Fail(footer_offset_, internal::kOpFooter,
                "summary_start " + std::to_string(summary_start_) + " or summary_offset_start " +
                    std::to_string(summary_offset_start_) + " lies outside the file's sections");
  }
  data_limit_ = summary_start_ != 0
                    ? summary_start_
                    : (summary_offset_start_ != 0 ? summary_offset_start_ : footer_offset_);
  if (summary_start_ != 0 && summary_crc != 0) CheckSummaryCrc(summary_crc);
}

// The CRC-32 from the summary's first byte through the footer's summary_offset_start field.
void McapReader::CheckSummaryCrc(uint32_t summary_crc) const {
  const uint64_t end = footer_offset_ + kMcapRecordPrefixBytes + 16;
  const uint32_t crc = Crc32(bytes_.substr(summary_start_, end - summary_start_));
  if (crc != summary_crc) {
    place_.Fail(footer_offset_, internal::kOpFooter,
                "the CRC-32 of the summary section is " + Hex(crc) + ", the footer says " +
                    Hex(summary_crc) + " (corrupt data)");
  }
}

// The data section's CRC from its Data End record, found just before data_limit_ (0 when
// absent or not computed by the writer).
uint32_t McapReader::DataEndCrc() const {
  constexpr uint64_t kDataEndBytes = kMcapRecordPrefixBytes + 4;
  if (data_limit_ - data_begin_ < kDataEndBytes) return 0;
  const uint64_t offset = data_limit_ - kDataEndBytes;
  uint64_t length;
  std::memcpy(&length, bytes_.data() + offset + 1, 8);
  if (static_cast<uint8_t>(bytes_[offset]) != internal::kOpDataEnd || length != 4) return 0;
  uint32_t crc;
  std::memcpy(&crc, bytes_.data() + offset + kMcapRecordPrefixBytes, 4);
  return crc;
}

// A file without channels in its summary: one pass over the data section for the Schema and
// Channel records (a message before its channel is refused here already).
void McapReader::ScanChannels() {
  McapDataWalker scan(path_, bytes_, data_begin_, data_limit_, 0);
  McapRecord record;
  std::vector<bool> defined(65536, false);
  while (scan.Next(&record)) {
    McapFields fields(record.content, record.content_offset, record.opcode, scan.place());
    if (record.opcode == internal::kOpSchema) {
      channels_.AddSchema(&fields);
    } else if (record.opcode == internal::kOpChannel) {
      defined[channels_.AddChannel(&fields, /*must_be_known=*/false)] = true;
    } else if (record.opcode == internal::kOpMessage) {
      const uint16_t channel_id = fields.U16("channel_id");
      if (!defined[channel_id]) {
        fields.Fail("refers to channel " + std::to_string(channel_id) +
                    ", which no Channel record before it defines");
      }
    }
  }
}

bool McapReader::Next(BagMessage* message) {
  McapRecord record;
  while (walker_->Next(&record)) {
    McapFields fields(record.content, record.content_offset, record.opcode, walker_->place());
    switch (record.opcode) {
      case internal::kOpSchema:
        channels_.AddSchema(&fields);
        break;
      case internal::kOpChannel:
        defined_in_data_[channels_.AddChannel(&fields, /*must_be_known=*/true)] = true;
        break;
      case internal::kOpMessage: {
        const uint16_t channel_id = fields.U16("channel_id");
        if (!defined_in_data_[channel_id]) {
          fields.Fail("refers to channel " + std::to_string(channel_id) +
                      ", which no Channel record before it defines");
        }
        fields.U32("sequence");
        message->connection_id = channel_id;
        message->log_time_ns = fields.Time("log_time");
        fields.Time("publish_time");
        message->data = fields.Rest();
        message->file_offset = record.file_offset;
        return true;
      }
      default:
        break;  // indexes, attachments, metadata and unknown records carry no messages
    }
  }
  return false;
}

}  // namespace

std::unique_ptr<BagReader> OpenMcap(const std::string& path) {
  return std::make_unique<McapReader>(path);
}

}  // namespace import
}  // namespace autocal
