// The exact 49-frame camera tables of the six trajectories shipped with the authors' code (generated into
// trajectory_official_tables.cpp from tests/data/official-code-trajectories.tsv).
#pragma once
#include <span>
#include <string>
#include <vector>

namespace dvs::geometry {

struct OfficialFrame {
  double theta_deg;  // rotation about the camera x axis
  double phi_deg;    // rotation about the camera y axis
  double r;          // dolly, in units of the radius
};

struct OfficialTable {
  std::string name;  // loop1 loop2 loop3 loop4 oscillating_wave wave1
  std::span<const OfficialFrame> frames;  // 49 entries
};

const std::vector<OfficialTable>& official_tables();

}  // namespace dvs::geometry
