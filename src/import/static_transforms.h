#pragma once

// The static transform tree of a bag's /tf_static, and the transform between any two of
// its frames. Private to src/import.

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "autocal/geometry/se3.h"
#include "import/ros_messages.h"

namespace autocal {
namespace import {

class StaticTransforms {
 public:
  // A later transform of the same child replaces the earlier one (latched /tf_static
  // publishers repeat theirs).
  void Add(const std::vector<StampedTransform>& transforms);
  size_t size() const { return parent_of_.size(); }

  // T_a_b, p_a = T_a_b * p_b, when both frames lie in one tree; nullopt otherwise. Frame
  // names are compared without a leading '/' (ROS 1 tf_prefix style).
  std::optional<geometry::Pose3d> Find(const std::string& a, const std::string& b) const;

 private:
  struct Edge {
    std::string parent;
    geometry::Pose3d T_parent_child;
  };
  // T_root_frame and the root's name, following parents (at most size() steps, so a
  // cycle cannot loop).
  geometry::Pose3d ToRoot(const std::string& frame, std::string* root) const;

  std::map<std::string, Edge> parent_of_;
};

// `frame` without a leading '/'.
std::string CanonicalFrame(const std::string& frame);

}  // namespace import
}  // namespace autocal
