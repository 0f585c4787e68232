#pragma once

// One result of a nearest-neighbour search (KdTree, NeighborGrid).

namespace autocal {
namespace lidar {

struct Neighbor {
  int index = -1;  // column of the point in the searched set
  double squared_distance_m2 = 0.0;
};

}  // namespace lidar
}  // namespace autocal
