// One ROI as the tracker saw it, with the tracked pattern drawn at the reported pose: the
// pattern's square and inscribed circle (the correlation mask) turned by phi, a heading line
// along the pattern's +x axis, and the pattern's own strongest edges turned and placed at
// (x, y) — if they lie on the target's edges in the picture, the pose is right. Colour by
// state: green TRACKING, yellow ACQUIRING, red LOST. Rotation as everywhere in sempose:
// counter-clockwise on screen (y down), about the pattern centre.
#pragma once

#include <utility>
#include <vector>

#include "sempose/hal/image.hpp"
#include "sempose/operator_view/pose_csv.hpp"
#include "sempose/operator_view/rgb_image.hpp"

namespace sempose::operator_view {

// Offsets (u, v) from the pattern centre of its strongest gradient pixels: the top
// `keep_fraction` of Sobel magnitudes inside the inscribed circle.
std::vector<std::pair<float, float>> pattern_edge_points(const hal::Image& pattern, double keep_fraction = 0.06);

// Crop of `frame` (roi_px square, centred on the pose, clamped to the field), grey, enlarged
// `scale` times, with the overlay. pattern_px: the pattern's side.
RgbImage render_roi(const hal::Image& frame, const PoseRow& pose, int roi_px, int pattern_px,
                    const std::vector<std::pair<float, float>>& edges, int scale);

}  // namespace sempose::operator_view
