#include <hindsight/problems/rod/rod_config.h>

#include <hindsight/engine/deterministic_math.h>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {
namespace {

template <typename T>
[[noreturn]] void fail(const char* field, T value, const std::string& range) {
  std::ostringstream message;
  message.precision(17);
  message << "RodConfig." << field << " = " << value << " is outside the allowed range " << range;
  throw std::invalid_argument(message.str());
}

void requireFinitePositive(const char* field, double value) {
  if (!std::isfinite(value) || !(value > 0.0)) fail(field, value, "(0, inf)");
}

}  // namespace

void RodConfig::validate() const {
  if (elementsAlongLength < 3) fail("elementsAlongLength", elementsAlongLength, "[3, inf)");
  if (elementsThroughHeight < 2 || elementsThroughHeight % 2 != 0)
    fail("elementsThroughHeight", elementsThroughHeight, "even integers >= 2");
  requireFinitePositive("length", length);
  requireFinitePositive("height", height);
  requireFinitePositive("thickness", thickness);
  requireFinitePositive("youngsModulus", youngsModulus);
  requireFinitePositive("density", density);
  if (!std::isfinite(poissonRatio) || !(poissonRatio > -1.0 && poissonRatio < 0.5))
    fail("poissonRatio", poissonRatio, "(-1, 0.5)");
  if (!std::isfinite(stiffnessPenalty) || !(stiffnessPenalty >= 1.0))
    fail("stiffnessPenalty", stiffnessPenalty, "[1, inf)");
  requireFinitePositive("massLawFactor", massLawFactor);
  if (!std::isfinite(massLawExponent) || !(massLawExponent >= 1.0))
    fail("massLawExponent", massLawExponent, "[1, inf)");
  if (!std::isfinite(massLawThreshold) || !(massLawThreshold > 0.0 && massLawThreshold <= 1.0))
    fail("massLawThreshold", massLawThreshold, "(0, 1]");
  // The density law must be continuous at the threshold (docs/design.md §2), otherwise the objective jumps
  // there.
  const double continuityFactor = dmath::pow(massLawThreshold, 1.0 - massLawExponent);
  if (std::abs(massLawFactor - continuityFactor) > 1e-9 * continuityFactor) {
    std::ostringstream range;
    range.precision(17);
    range << "{threshold^(1 - q)} = {" << continuityFactor << "} (density law continuous at the threshold)";
    fail("massLawFactor", massLawFactor, range.str());
  }
  if (!std::isfinite(designLowerBound) || !(designLowerBound > 0.0 && designLowerBound < 1.0))
    fail("designLowerBound", designLowerBound, "(0, 1)");
  if (!std::isfinite(initialDesign) || !(initialDesign >= designLowerBound && initialDesign <= 1.0))
    fail("initialDesign", initialDesign,
         "[designLowerBound, 1] = [" + std::to_string(designLowerBound) + ", 1]");
  if (modeCount < 1) fail("modeCount", modeCount, "[1, inf)");
  if (elementsThroughThickness < 0 || elementsThroughThickness > 10000)
    fail("elementsThroughThickness", elementsThroughThickness, "[0, 10000] (0: the plate, >= 1: the solid)");
  if (midPlaneSymmetry && !isSolid())
    fail("midPlaneSymmetry", "true", "{false} for the plate (elementsThroughThickness = 0)");
  // The inertia-relief modes' design derivatives exist for neither member, and the solid's basis is the
  // eigenmodes' alone.
  if (inertiaReliefModes && isSolid())
    fail("inertiaReliefModes", "true", "{false} for the solid (elementsThroughThickness >= 1)");
  if (!std::isfinite(crankRadius) || !(crankRadius > 0.0 && crankRadius < length))
    fail("crankRadius", crankRadius, "(0, length) = (0, " + std::to_string(length) + ")");
  requireFinitePositive("crankSpeed", crankSpeed);
  requireFinitePositive("rampTime", rampTime);
  if (!std::isfinite(endTime) || !(endTime >= rampTime))
    fail("endTime", endTime, "[rampTime, inf) = [" + std::to_string(rampTime) + ", inf)");
  if (eslSamples < 1) fail("eslSamples", eslSamples, "[1, inf)");
}

}  // namespace rod
}  // namespace hindsight
