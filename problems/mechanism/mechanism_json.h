// The `mechanism` section of the configuration: reading (strict: an unknown key, a wrong type or an
// out-of-range value throws std::invalid_argument naming the element and field, e.g.
// "mechanism.joints[crankPin].type = 'hinge' must be one of: revolute, prismatic, fixed") and writing.
// The format is documented in docs/tutorials/own_mechanism.md; examples/mechanisms/ holds examples.
#pragma once

#include <hindsight/problems/mechanism/mechanism.h>

#include <nlohmann/json.hpp>

namespace hindsight::mechanism {

/// Reads the section; the member's length is left at its default (the configuration sets it from
/// rod.length). Calls Mechanism::validate().
Mechanism mechanismFromJson(const nlohmann::json& json, double memberLength);
nlohmann::json toJson(const Mechanism& mechanism);

}  // namespace hindsight::mechanism
