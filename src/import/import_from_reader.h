#pragma once

// ImportBag on a reader that is already open: the same steps, for a container the caller
// provides (tests use an in-memory reader of CDR messages). Private to src/import.

#include "autocal/import/import_bag.h"
#include "import/bag_reader.h"

namespace autocal {
namespace import {

// options.input is not used; the output is checked before the first message is read.
ImportSummary ImportFromReader(BagReader* reader, const ImportOptions& options);

}  // namespace import
}  // namespace autocal
