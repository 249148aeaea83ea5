// x, y, phi and score over time, one panel each, one line per target: a gnuplot data file
// and script next to the PNG, so the plot can be redrawn or restyled by hand.
#pragma once

#include <string>
#include <vector>

#include "sempose/operator_view/pose_csv.hpp"

namespace sempose::operator_view {

// Writes <stem>.dat and <stem>.gp; runs gnuplot -d (the user's ~/.gnuplot not read; stopped
// after 20 s) to make <stem>.png. Returns "" on success, else what went wrong (gnuplot missing,
// failing or stuck; a <stem>.png it left is removed), with the command to run by hand. Throws
// std::runtime_error, the cut file removed, when a file could not be written whole.
std::string plot_track(const std::vector<PoseRow>& rows, const std::string& stem, const std::string& title);

}  // namespace sempose::operator_view
