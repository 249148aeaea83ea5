#pragma once
// How much of a pattern's position information lies at its rim (setup only; allocates).
// A target that reaches the pattern's rim is placed, along the axis it fills, by the few pixels
// beyond its ends, which are background recorded with it: wherever the target moves the
// background differs there, and its structure pulls the pose. The procedural lamella 60 px long
// in a 64 px pattern recorded over another patch of background (`replay --truth`, ~60 e-/px):
// 14 of 25 TRACKING poses 3.8-5 px off along its length at σx 0.6-0.9 px — nothing in a frame
// tells that pull from the target. The information along x (y) is Σ gx² (Σ gy²) of the
// prefiltered pattern over the circle the tracker scores; its share in the outer kRimFraction of
// the radius is compared with kRimShareWarn. That lamella reads 0.58 along x where the ring holds
// 0.23 of the circle's area; the needle tip (128 px), the lamella on post and a lamella with a
// margin read 0.18-0.23 on both axes.
#include <cstdint>
#include <string>

namespace sempose::pose {

struct RimShare {
  double x = 0, y = 0;  // shares of the position information along x / y in the rim ring
  double area = 0;      // the ring's share of the circle's pixels (a uniform texture's share)
  int ring_px = 0;      // the ring's width
  bool valid = false;   // the pattern has structure (a flat one has no information to share)
};

inline constexpr double kRimFraction = 0.125;
inline constexpr double kRimShareWarn = 0.5;

// pixels: the pattern as recorded (n×n); prefilter_passes: the tracker's prefilter.
RimShare rim_information_share(const std::uint16_t* pixels, int n, int prefilter_passes);

// "" when neither axis reaches kRimShareWarn; else what the user should know and do.
std::string rim_warning(const RimShare& r);

}  // namespace sempose::pose
