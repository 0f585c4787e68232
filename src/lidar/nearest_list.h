#pragma once

// The k nearest neighbours found so far, as the searches of lidar/ keep them (KdTree,
// NeighborGrid): sorted by squared distance, ties by the lower index.

#include "autocal/lidar/neighbor.h"

namespace autocal {
namespace lidar {
namespace internal {

// Whether (d_a, i_a) comes before (d_b, i_b).
inline bool Closer(double d_a, int i_a, double d_b, int i_b) {
  return d_a < d_b || (d_a == d_b && i_a < i_b);
}

// Offers the point `index` at squared distance d to out[0 .. *count), at most k entries; a
// point kept carries `tag` into tags (moved alongside out) when tags is not null. Forced inline:
// called from the k-d tree's recursive search, an out-of-line call cost its k-NN 10-15 %.
template <typename Tag>
inline __attribute__((always_inline)) void OfferNearest(int k, double d, int index, Tag tag,
                                                        Neighbor* out, Tag* tags, int* count) {
  int i;
  if (*count < k) {
    i = (*count)++;
  } else if (Closer(d, index, out[k - 1].squared_distance_m2, out[k - 1].index)) {
    i = k - 1;
  } else {
    return;
  }
  while (i > 0 && Closer(d, index, out[i - 1].squared_distance_m2, out[i - 1].index)) {
    out[i] = out[i - 1];
    if (tags != nullptr) tags[i] = tags[i - 1];
    --i;
  }
  out[i] = Neighbor{index, d};
  if (tags != nullptr) tags[i] = tag;
}

}  // namespace internal
}  // namespace lidar
}  // namespace autocal
