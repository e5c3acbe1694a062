#include "camera_source.hpp"

#include "dataset.hpp"
#include "io.hpp"

namespace fs::app {

capture::OpenHooks camera_hooks() {
  capture::OpenHooks h;
  h.list_dataset = [](const std::string& dir) {
    std::vector<capture::PairPaths> pairs;
    std::vector<Frame> frames;
    try {
      frames = discover_dataset(dir);
    } catch (const UserError&) {
      return pairs;  // not a dataset: open_camera reports every layout it looked for
    }
    for (const Frame& f : frames) pairs.push_back({f.left_path, f.right_path, -1});
    return pairs;
  };
  return h;
}

std::unique_ptr<capture::StereoCamera> open_stereo_source(const std::string& source, const capture::CameraParams& p) {
  return capture::open_camera(capture::parse_source(source), p, camera_hooks());
}

}  // namespace fs::app
