#include "import/static_transforms.h"

namespace autocal {
namespace import {

std::string CanonicalFrame(const std::string& frame) {
  return !frame.empty() && frame.front() == '/' ? frame.substr(1) : frame;
}

void StaticTransforms::Add(const std::vector<StampedTransform>& transforms) {
  for (const StampedTransform& transform : transforms) {
    parent_of_[CanonicalFrame(transform.child_frame)] =
        Edge{CanonicalFrame(transform.parent_frame), transform.T_parent_child};
  }
}

geometry::Pose3d StaticTransforms::ToRoot(const std::string& frame, std::string* root) const {
  geometry::Pose3d T_root_frame = geometry::Pose3d::Identity();
  std::string current = frame;
  for (size_t steps = 0; steps <= parent_of_.size(); ++steps) {
    const auto it = parent_of_.find(current);
    if (it == parent_of_.end()) break;
    T_root_frame = it->second.T_parent_child * T_root_frame;
    current = it->second.parent;
  }
  *root = current;
  return T_root_frame;
}

std::optional<geometry::Pose3d> StaticTransforms::Find(const std::string& a,
                                                       const std::string& b) const {
  const std::string frame_a = CanonicalFrame(a);
  const std::string frame_b = CanonicalFrame(b);
  if (frame_a.empty() || frame_b.empty()) return std::nullopt;
  if (frame_a == frame_b) return geometry::Pose3d::Identity();
  std::string root_a, root_b;
  const geometry::Pose3d T_root_a = ToRoot(frame_a, &root_a);
  const geometry::Pose3d T_root_b = ToRoot(frame_b, &root_b);
  if (root_a != root_b) return std::nullopt;
  return T_root_a.Inverse() * T_root_b;
}

}  // namespace import
}  // namespace autocal
