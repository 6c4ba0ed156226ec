// Whether the frames show a highlight on an object: the same texel seen from frames where a light
// sits in the mirror direction and from frames where none does. Their radiance ratio cancels the
// albedo and the irradiance, so what is left (the contrast) is the view-dependent part. Decides
// which objects' roughness and specular the data constrains.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

namespace relume {

class HighlightEvidence {
 public:
  explicit HighlightEvidence(int objects);

  // One batch of connections, grouped by slot (a slot's rays contiguous, all on one texel of
  // `object[i]`): `luminance` of each ray's reference, `sawLight` 1 if a light is reflected
  // towards the camera there, 0 if not, -1 if the ray does not count (masked, no hit).
  void addBatch(std::span<const uint32_t> slot, std::span<const int> object, std::span<const float> luminance,
                std::span<const int8_t> sawLight);

  uint64_t texels(int object) const { return texels_[object]; }  // texels seen both ways
  double contrast(int object) const;                             // mean of (with / without - 1)
  double standardError(int object) const;
  // At least `minTexels` texels, and a mean contrast that exceeds `minContrast` by two standard errors.
  bool observed(int object, int minTexels, double minContrast) const;

 private:
  std::vector<uint64_t> texels_;
  std::vector<double> sum_, sumSquares_;
};

// What the absence of a highlight says about an object's roughness (its specular as it is). The
// frames' contrast on its texels (`observed` +- `observedError`) is set against the contrast the
// model renders on the same connections with the object at each roughness of `grid` (ascending,
// ending at the roughest, 1): a roughness is ruled out where its rendered contrast exceeds the
// observed one by more than two standard errors of their difference (a highlight the frames would
// have shown; a negative contrast counts as 0). The run of allowed roughnesses that reaches the
// roughest is [atLeast, 1]; nothing in the frames prefers one roughness in it to another, and its
// middle (`chosen`) is the choice whose worst error over it is smallest. When even the roughest is
// ruled out (a contrast the model cannot make as small as the frames' at this specular), the
// roughest is taken.
//
// A smoother roughness allowed below the ruled-out ones is a second branch: a lobe so sharp that
// it never pointed at a light from the frames' views (the frames' "with a light reflected" texels
// see a light within about 10 degrees of the mirror direction, outside such a lobe). The absence
// of a highlight cannot tell it from a rough lobe. `sharpBelow` is then the roughness under which
// the frames allow it (half way between the grid's last allowed and first ruled-out roughness);
// the bound [atLeast, 1] holds for a lobe no sharper than that.
struct RoughnessFromAbsence {
  float atLeast = 1;
  float chosen = 1;
  bool roughestRuledOut = false;
  float sharpBelow = -1;  // -1: no sharp branch
  bool sharpBranch() const { return sharpBelow >= 0; }
};
RoughnessFromAbsence roughnessFromAbsence(double observed, double observedError, std::span<const float> grid,
                                          std::span<const double> rendered, std::span<const double> renderedError);

}  // namespace relume
