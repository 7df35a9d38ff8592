// Fuzzing the `mechanism` section of the configuration (problems/mechanism/mechanism_json.h,
// Mechanism::validate, the assembly at t = 0 in MechanismProblem): a description comes from a user's
// file or a Python dict, so whatever it holds, configFromJson must either return a configuration or
// throw std::invalid_argument naming what it refused -- never another exception type, a crash, a
// hang or undefined behaviour (the sanitizer build runs these tests too). An accepted description
// must then evaluate, on a tiny mesh over a short time, to a finite psi1 and gradient or fail with a
// NumericalError that says why. The seeds are the examples of examples/mechanisms/ and two
// mechanisms with the parts they do not use (springs, a fixed joint, a free coordinate, a
// constant-speed driver).
#include "fuzz/fuzz_support.h"
#include "support/run_cli.h"
#include "support/storage_fixtures.h"

#include <hindsight/engine/types.h>
#include <hindsight/problems/app/config.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/mechanism/mechanism_json.h>

#include <cmath>
#include <limits>
#include <map>
#include <set>

namespace hindsight {
namespace {

using nlohmann::json;

const char* const kLists[] = {"rigidBodies", "joints", "drivers", "springs", "free"};

// The parser's vocabulary: every key and keyword of the section, the seeds' names, numbers at the
// edges of double, and JSON's structural characters.
std::vector<std::string> dictionary() {
  std::vector<std::string> words = {"\"mechanism\"",
                                    "\"gravity\"",
                                    "\"ground\"",
                                    "\"points\"",
                                    "\"rigidBodies\"",
                                    "\"flexibleMember\"",
                                    "\"joints\"",
                                    "\"drivers\"",
                                    "\"springs\"",
                                    "\"free\"",
                                    "\"name\"",
                                    "\"mass\"",
                                    "\"inertia\"",
                                    "\"position\"",
                                    "\"angle\"",
                                    "\"type\"",
                                    "\"body1\"",
                                    "\"point1\"",
                                    "\"body2\"",
                                    "\"point2\"",
                                    "\"axis\"",
                                    "\"joint\"",
                                    "\"law\"",
                                    "\"speed\"",
                                    "\"rampTime\"",
                                    "\"offset\"",
                                    "\"stiffness\"",
                                    "\"restLength\"",
                                    "\"damping\"",
                                    "\"body\"",
                                    "\"coordinate\"",
                                    "\"velocity\"",
                                    "\"revolute\"",
                                    "\"prismatic\"",
                                    "\"fixed\"",
                                    "\"cycloidal-ramp\"",
                                    "\"constant-speed\"",
                                    "\"x\"",
                                    "\"y\"",
                                    "\"A\"",
                                    "\"B\"",
                                    "\"ground\"",
                                    "\"crank\"",
                                    "\"slider\"",
                                    "\"rod\"",
                                    "\"rocker\"",
                                    "\"coupler\"",
                                    "\"bob\"",
                                    "\"O\"",
                                    "\"pin\"",
                                    "\"center\"",
                                    "1e400",
                                    "-1e400",
                                    "1e-400",
                                    "-0",
                                    "0",
                                    "-1",
                                    "1e300",
                                    "4.9e-324",
                                    "NaN",
                                    "null",
                                    "true",
                                    "false",
                                    "\"\"",
                                    "[]",
                                    "{}",
                                    "[0, 0]",
                                    "[1e300, 1e300]",
                                    "{",
                                    "}",
                                    "[",
                                    "]",
                                    ",",
                                    ":",
                                    "\"",
                                    "\\u0000"};
  return words;
}

// Values of every JSON type and edge, including non-finite doubles (which a json object can hold, as
// a Python dict can, though JSON text cannot).
std::vector<json> interestingValues() {
  const double inf = std::numeric_limits<double>::infinity();
  return {json(nullptr),
          json(true),
          json(0),
          json(-1),
          json(1),
          json(0.5),
          json(-0.0),
          json(1e-300),
          json(1e300),
          json(-1e300),
          json(std::numeric_limits<double>::denorm_min()),
          json(std::numeric_limits<double>::max()),
          json(std::numeric_limits<double>::quiet_NaN()),
          json(inf),
          json(-inf),
          json(std::numeric_limits<std::int64_t>::min()),
          json(std::numeric_limits<std::uint64_t>::max()),
          json(""),
          json("ground"),
          json("rod"),
          json("A"),
          json("B"),
          json("revolute"),
          json("prismatic"),
          json("fixed"),
          json("constant-speed"),
          json("angle"),
          json::array(),
          json::array({0.0, 0.0}),
          json::array({1e300, -1e300}),
          json::array({1.0, inf}),
          json::array({1.0}),
          json::array({1.0, 2.0, 3.0}),
          json::array({"a", "b"}),
          json::object(),
          json::object({{"x", 1}})};
}

// The mesh and time span of the evaluations: milliseconds each (the Python tests' TINY).
void makeTiny(Config& config) {
  for (const char* setting :
       {"rod.elementsAlongLength=8", "rod.elementsThroughHeight=2", "rod.modeCount=2", "rod.rampTime=0.01",
        "rod.endTime=0.02", "rod.eslSamples=4", "simulation.step=1e-3"})
    applySetting(config, setting, /*validate=*/false);
}

json tinySections(json input) {
  input["rod"] = {{"elementsAlongLength", 8}, {"elementsThroughHeight", 2},
                  {"modeCount", 2},           {"rampTime", 0.01},
                  {"endTime", 0.02},          {"eslSamples", 4}};
  input["simulation"] = {{"step", 1e-3}};
  return input;
}

struct Outcome {
  bool accepted = false;
  std::string message;  // of the refusal
};

// The properties of an accepted configuration with a mechanism: it reads back from its own JSON, and
// the tiny evaluation gives a finite psi1 and gradient or a NumericalError with a message.
void expectSoundMechanism(const Config& accepted, const std::string& input, bool evaluate) {
  ASSERT_TRUE(accepted.mechanism.has_value()) << input;
  try {
    const json out = toJson(accepted);
    EXPECT_EQ(toJson(configFromJson(out)), out) << input;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "an accepted mechanism does not read back: " << e.what() << "\n"
                  << fuzz::printable(input);
  }
  if (!evaluate) return;
  Config config = accepted;
  try {
    makeTiny(config);
    config.validate();
  } catch (const std::invalid_argument&) {
    return;  // another section of a mutated file conflicts with the tiny settings
  }
  try {
    const PistonRod rod(config);
    PistonRod::Request request;
    request.psi2 = false;
    request.psi2Gradient = false;
    const PistonRodEvaluation e = rod.evaluate(rod.initialDesign(), request);
    EXPECT_TRUE(std::isfinite(e.psi1) && e.psi1 >= 0.0) << "psi1 = " << e.psi1 << " for\n"
                                                        << fuzz::printable(input);
    EXPECT_TRUE(e.dpsi1.allFinite()) << "a non-finite gradient for\n" << fuzz::printable(input);
  } catch (const NumericalError& e) {
    EXPECT_GT(std::string(e.what()).size(), 10u) << input;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "the evaluation threw " << typeid(e).name() << " (" << e.what() << ") for\n"
                  << fuzz::printable(input);
  }
}

// Runs `read`; passes when it returns a sound configuration or throws std::invalid_argument.
template <typename Read>
Outcome expectConfigOrInvalidArgument(Read&& read, const std::string& input, bool evaluate) {
  Outcome outcome;
  try {
    const Config config = read();
    outcome.accepted = true;
    expectSoundMechanism(config, input, evaluate);
  } catch (const std::invalid_argument& e) {
    outcome.message = e.what();
    EXPECT_FALSE(outcome.message.empty()) << input;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw " << typeid(e).name() << " (" << e.what()
                  << ") instead of std::invalid_argument for\n"
                  << fuzz::printable(input);
  }
  return outcome;
}

std::vector<json> seeds() {
  std::vector<json> out;
  for (const std::string& text : fuzz::seedFiles("mechanism_")) out.push_back(json::parse(text));
  return out;
}

TEST(MechanismFuzz, SeedsAreValidMechanismsThatEvaluate) {
  const auto all = seeds();
  ASSERT_GE(all.size(), 5u);
  for (const json& seed : all) {
    const Outcome outcome =
        expectConfigOrInvalidArgument([&] { return configFromJson(tinySections(seed)); }, seed.dump(), true);
    EXPECT_TRUE(outcome.accepted) << outcome.message;
  }
}

// Mutated JSON text through readConfigFile (the file reader's parse errors included).
TEST(MechanismFuzz, MutatedJsonFiles) {
  const auto texts = fuzz::seedFiles("mechanism_");
  const auto words = dictionary();
  fuzz::Mutator mutator(fuzz::seed(21));
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/hindsight_fuzz_mechanism.json";
  int accepted = 0;
  for (int k = 0; k < fuzz::cases(1200); ++k) {
    const std::string text = mutator.mutate(mutator.pick(texts), words, 5);
    fuzz::writeText(path, text);
    // Each accepted description is evaluated: a mutation that still parses changes a number or a name.
    const Outcome outcome = expectConfigOrInvalidArgument([&] { return readConfigFile(path); }, text, true);
    accepted += outcome.accepted ? 1 : 0;
    if (HasFailure()) return;  // the first failing input is the useful one
  }
  ::testing::Test::RecordProperty("accepted", accepted);
}

// A path into the section: the list and the element's index (-1: the section itself, or the
// flexible member / ground / gravity by `list`).
struct Target {
  std::string list;
  int index = -1;
};

// Structured mutations: valid JSON with fields of the section set to values of every type and edge,
// keys deleted, unknown keys, elements duplicated (duplicate names) or deleted, lists emptied or
// replaced, references to unknown bodies, points and joints, joints between a body and itself.
TEST(MechanismFuzz, RandomFieldValues) {
  const auto all = seeds();
  const auto values = interestingValues();
  const std::vector<std::string> fieldNames = {
      "name",       "mass",     "inertia", "position",  "angle",      "points",  "type",
      "body1",      "point1",   "body2",   "point2",    "axis",       "joint",   "law",
      "speed",      "rampTime", "offset",  "stiffness", "restLength", "damping", "body",
      "coordinate", "velocity", "gravity", "ground",    "colour"};
  fuzz::Mutator mutator(fuzz::seed(22));
  int accepted = 0;
  for (int k = 0; k < fuzz::cases(1500); ++k) {
    json input = tinySections(mutator.pick(all));
    json& m = input["mechanism"];
    const int edits = 1 + static_cast<int>(mutator.below(3));
    for (int e = 0; e < edits && m.is_object(); ++e) {
      const std::string list = kLists[mutator.below(std::size(kLists))];
      json* element = nullptr;
      if (m.contains(list) && m[list].is_array() && !m[list].empty()) {
        element = &m[list][mutator.below(m[list].size())];
      }
      switch (mutator.below(12)) {
        case 0:  // the section or a list replaced by any value
          if (mutator.chance(0.1))
            m = mutator.pick(values);
          else
            m[list] = mutator.pick(values);
          break;
        case 1:  // a list emptied or deleted
          if (mutator.chance(0.5))
            m[list] = json::array();
          else
            m.erase(list);
          break;
        case 2:  // an element duplicated (its name used twice)
          if (element != nullptr) m[list].push_back(json(*element));
          break;
        case 3:  // an element deleted
          if (element != nullptr) m[list].erase(mutator.below(m[list].size()));
          break;
        case 4:  // a key of an element deleted
          if (element != nullptr && element->is_object() && !element->empty()) {
            auto it = element->begin();
            std::advance(it, static_cast<long>(mutator.below(element->size())));
            element->erase(it.key());
          }
          break;
        case 5:  // a reference to a body of the seed, itself, or nothing
          if (element != nullptr && element->is_object()) {
            const char* key = mutator.pick(std::vector<const char*>{"body1", "body2", "body", "joint"});
            const json other = element->contains("body1") ? (*element)["body1"] : json("ground");
            (*element)[key] = mutator.chance(0.5) ? other : mutator.pick(values);
          }
          break;
        case 6:  // the flexible member, the ground or gravity
          switch (mutator.below(3)) {
            case 0:
              m["flexibleMember"][mutator.pick(std::vector<std::string>{"name", "position", "angle", "x"})] =
                  mutator.pick(values);
              break;
            case 1:
              m["ground"]["points"][mutator.pick(std::vector<std::string>{"O", "O2", "S", ""})] =
                  mutator.pick(values);
              break;
            default:
              m["gravity"] = mutator.pick(values);
          }
          break;
        case 7:  // a point of a body
          if (element != nullptr && element->is_object() && list == "rigidBodies")
            (*element)["points"][mutator.pick(std::vector<std::string>{"O", "pin", "hook", "A", ""})] =
                mutator.pick(values);
          break;
        case 8:  // a numeric field scaled far out of its range or negated
          if (element != nullptr && element->is_object()) {
            for (auto& [key, value] : element->items()) {
              if (value.is_number() && mutator.chance(0.5))
                value = value.get<double>() * (mutator.chance(0.5) ? -1.0 : 1e200);
            }
          }
          break;
        default:  // any field of an element set to any value
          if (element != nullptr && element->is_object())
            (*element)[mutator.pick(fieldNames)] = mutator.pick(values);
      }
    }
    const std::string text = input.dump(-1, ' ', false, json::error_handler_t::replace);
    const Outcome outcome = expectConfigOrInvalidArgument([&] { return configFromJson(input); }, text,
                                                          /*evaluate=*/mutator.chance(0.5));
    if (!outcome.accepted && !HasFailure()) {
      // Only the mechanism section was edited: the refusal names it.
      EXPECT_NE(outcome.message.find("mechanism"), std::string::npos) << outcome.message << "\n" << text;
    }
    accepted += outcome.accepted ? 1 : 0;
    if (HasFailure()) return;
  }
  EXPECT_GT(accepted, 30);  // the mutations reach past the parser
  ::testing::Test::RecordProperty("accepted", accepted);
}

// One fault at a time in a valid description: the refusal names the element (by its name) and the
// field, e.g. "mechanism.rigidBodies[rocker].mass = -1 is outside the allowed range [0, inf)".
TEST(MechanismFuzz, EverySingleFaultIsNamedWithItsElementAndField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  // Faults by the kind of field: values no field of that kind may take.
  const std::vector<json> badNumbers = {json(nan),     json(inf),  json(-inf),    json("1"),
                                        json(nullptr), json(true), json::array(), json::object()};
  const std::vector<json> badNonNegative = {json(-1.0), json(-1e-300), json(-1e300)};
  const std::vector<json> badVectors = {json(1.0),
                                        json::array(),
                                        json::array({1.0}),
                                        json::array({1, 2, 3}),
                                        json::array({nan, 0.0}),
                                        json::array({0.0, inf}),
                                        json::array({"a", 0.0}),
                                        json("[0, 0]"),
                                        json(nullptr)};
  const std::vector<json> badTexts = {json(1), json(nullptr), json(true), json::array(), json::object()};
  const std::vector<json> badReferences = {json("nowhere"), json(""), json("Ground")};
  const std::set<std::string> nonNegative = {"mass", "inertia", "stiffness", "restLength", "damping"};
  const std::set<std::string> numbers = {"mass",   "inertia",  "angle",     "speed",      "rampTime",
                                         "offset", "velocity", "stiffness", "restLength", "damping"};
  const std::set<std::string> vectors = {"position", "axis"};
  const std::set<std::string> references = {"body1", "point1", "body2", "point2",    "joint",
                                            "body",  "type",   "law",   "coordinate"};
  int cases = 0;
  for (const json& seed : seeds()) {
    for (const char* list : kLists) {
      if (!seed["mechanism"].contains(list)) continue;
      const json& elements = seed["mechanism"][list];
      for (std::size_t i = 0; i < elements.size(); ++i) {
        const json& element = elements[i];
        // How the messages name the element: by its name, or the free coordinate by its index.
        const std::string where =
            std::string("mechanism.") + list +
            (element.contains("name") ? "[" + element["name"].get<std::string>() + "]" : "");
        for (const auto& [field, original] : element.items()) {
          std::vector<json> faults;
          if (numbers.count(field)) faults = badNumbers;
          if (nonNegative.count(field))
            faults.insert(faults.end(), badNonNegative.begin(), badNonNegative.end());
          if (field == "rampTime") faults.push_back(json(0.0));
          if (vectors.count(field)) faults = badVectors;
          if (field == "axis") faults.push_back(json::array({0.0, 0.0}));
          if (field == "name" || references.count(field)) faults = badTexts;
          if (references.count(field))
            faults.insert(faults.end(), badReferences.begin(), badReferences.end());
          for (const json& fault : faults) {
            json input = tinySections(seed);
            input["mechanism"][list][i][field] = fault;
            const std::string text =
                input["mechanism"][list][i].dump(-1, ' ', false, json::error_handler_t::replace);
            ++cases;
            try {
              configFromJson(input);
              ADD_FAILURE() << where << "." << field << " = " << fault.dump() << " accepted: " << text;
            } catch (const std::invalid_argument& e) {
              const std::string message = e.what();
              // A renamed element is named by its index or its new name; a wrong body name can also be
              // reported through the point it no longer has.
              const bool namesElement = message.find(where) != std::string::npos ||
                                        message.find(std::string("mechanism.") + list) != std::string::npos;
              std::string partner = field;
              if (field.rfind("body", 0) == 0 && field.size() == 5) partner = "point" + field.substr(4);
              const bool namesField =
                  message.find(field) != std::string::npos || message.find(partner) != std::string::npos;
              EXPECT_TRUE(namesElement && namesField)
                  << "'" << message << "' for " << where << "." << field << " = " << fault.dump();
            } catch (const std::exception& e) {
              ADD_FAILURE() << typeid(e).name() << " (" << e.what() << ") for " << where << "." << field
                            << " = " << fault.dump();
            }
          }
        }
      }
    }
  }
  EXPECT_GT(cases, 300);
}

// A random planar mechanism: bodies with random masses at random poses, joints of every type between
// random bodies placed so that the description assembles at t = 0 (each joint's points coincide
// there), drivers on some of them, springs, and as many free coordinates as the count asks for --
// or, now and then, one too many, a wrong reference or an impossible pose. Accepted ones are
// evaluated.
json randomMechanism(fuzz::Mutator& mutator, double length) {
  const auto uniform = [&](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(mutator.rng());
  };
  struct Pose {
    std::string name;
    double x, y, angle;
  };
  std::vector<Pose> bodies;  // rigid bodies, then the member
  const std::size_t rigid = mutator.below(4);
  for (std::size_t b = 0; b < rigid; ++b)
    bodies.push_back({"b" + std::to_string(b), uniform(-1, 1), uniform(-1, 1), uniform(-3, 3)});
  const Pose member{"rod", uniform(-1, 1), uniform(-1, 1), uniform(-3, 3)};
  json m;
  m["gravity"] = json::array({0.0, mutator.chance(0.5) ? -9.81 : 0.0});
  m["ground"]["points"] = json::object();
  m["rigidBodies"] = json::array();
  std::map<std::string, int> pointCount;
  for (const Pose& b : bodies) {
    m["rigidBodies"].push_back({{"name", b.name},
                                {"mass", mutator.chance(0.2) ? 0.0 : uniform(0.1, 3)},
                                {"inertia", mutator.chance(0.2) ? 0.0 : uniform(0.001, 0.1)},
                                {"position", {b.x, b.y}},
                                {"angle", b.angle},
                                {"points", json::object()}});
  }
  m["flexibleMember"] = {{"name", member.name}, {"position", {member.x, member.y}}, {"angle", member.angle}};
  // A body's point at the global position (gx, gy): its local coordinates in the body's frame.
  const auto attach = [&](int body, double gx, double gy) -> std::string {
    if (body < 0) {
      const std::string name = "g" + std::to_string(pointCount["ground"]++);
      m["ground"]["points"][name] = {gx, gy};
      return name;
    }
    const Pose& b = bodies[static_cast<std::size_t>(body)];
    const double c = std::cos(b.angle), s = std::sin(b.angle);
    const double dx = gx - b.x, dy = gy - b.y;
    const std::string name = "p" + std::to_string(pointCount[b.name]++);
    m["rigidBodies"][static_cast<std::size_t>(body)]["points"][name] = {c * dx + s * dy, -s * dx + c * dy};
    return name;
  };
  const auto nameOf = [&](int body) {
    return body < 0 ? std::string("ground") : bodies[static_cast<std::size_t>(body)].name;
  };
  const double ax = member.x, ay = member.y;
  const double bx = ax + length * std::cos(member.angle), by = ay + length * std::sin(member.angle);
  m["joints"] = json::array();
  m["drivers"] = json::array();
  m["springs"] = json::array();
  const int jointCount = static_cast<int>(mutator.below(static_cast<std::size_t>(2 + 2 * rigid)));
  const int others = static_cast<int>(rigid);  // bodies -1 (ground) .. rigid - 1
  for (int j = 0; j < jointCount; ++j) {
    const std::string type =
        mutator.pick(std::vector<std::string>{"revolute", "revolute", "prismatic", "fixed"});
    json joint = {{"name", "j" + std::to_string(j)}, {"type", type}};
    // One end on the member (A or B) half of the time, else between two different rigid bodies/ground.
    int body1 = static_cast<int>(mutator.below(static_cast<std::size_t>(others + 1))) - 1;
    if (mutator.chance(0.5)) {
      const bool atB = mutator.chance(0.5);
      joint["body1"] = nameOf(body1);
      joint["point1"] = attach(body1, atB ? bx : ax, atB ? by : ay);
      joint["body2"] = member.name;
      joint["point2"] = atB ? "B" : "A";
    } else {
      int body2 = static_cast<int>(mutator.below(static_cast<std::size_t>(others + 1))) - 1;
      if (body2 == body1) body2 = body1 + 1 < others ? body1 + 1 : -1;
      if (body1 == body2) continue;  // no rigid body: only the ground
      const double gx = uniform(-1, 1), gy = uniform(-1, 1);
      joint["body1"] = nameOf(body1);
      joint["point1"] = attach(body1, gx, gy);
      joint["body2"] = nameOf(body2);
      joint["point2"] = attach(body2, gx, gy);
    }
    if (type == "prismatic") {
      const double angle = uniform(-3, 3);
      joint["axis"] = {std::cos(angle), std::sin(angle)};
    }
    if (type != "fixed" && mutator.chance(0.4)) {
      // The offset is the joint's value at t = 0: the relative angle, or 0 for coinciding points.
      const auto angleOf = [&](const std::string& name) {
        if (name == "ground") return 0.0;
        if (name == member.name) return member.angle;
        for (const Pose& b : bodies)
          if (b.name == name) return b.angle;
        return 0.0;
      };
      const double offset = type == "revolute" ? angleOf(joint["body2"].get<std::string>()) -
                                                     angleOf(joint["body1"].get<std::string>())
                                               : 0.0;
      json driver = {{"name", "d" + std::to_string(j)},
                     {"joint", joint["name"]},
                     {"speed", uniform(-20, 20)},
                     {"offset", offset}};
      if (mutator.chance(0.5)) {
        driver["law"] = "cycloidal-ramp";
        driver["rampTime"] = uniform(0.005, 0.05);
      } else {
        driver["law"] = "constant-speed";
      }
      m["drivers"].push_back(driver);
    }
    m["joints"].push_back(joint);
  }
  for (std::size_t s = 0, count = mutator.below(3); s < count; ++s) {
    const int body1 = static_cast<int>(mutator.below(static_cast<std::size_t>(others + 1))) - 1;
    m["springs"].push_back({{"name", "s" + std::to_string(s)},
                            {"body1", nameOf(body1)},
                            {"point1", attach(body1, uniform(-1, 1), uniform(-1, 1))},
                            {"body2", member.name},
                            {"point2", mutator.chance(0.5) ? "A" : "B"},
                            {"stiffness", uniform(0, 100)},
                            {"restLength", uniform(0, 1)},
                            {"damping", uniform(0, 1)}});
  }
  // As many free coordinates as the count asks for (when the rigid bodies have them), sometimes one
  // more or less.
  int constraints = static_cast<int>(m["drivers"].size());
  for (const json& joint : m["joints"]) constraints += joint["type"] == "fixed" ? 3 : 2;
  int dof = 3 * static_cast<int>(rigid) + 3 - constraints;
  if (mutator.chance(0.1)) dof += mutator.chance(0.5) ? 1 : -1;
  m["free"] = json::array();
  std::vector<std::pair<std::size_t, std::string>> coordinates;
  for (std::size_t b = 0; b < rigid; ++b)
    for (const char* c : {"x", "y", "angle"}) coordinates.emplace_back(b, c);
  std::shuffle(coordinates.begin(), coordinates.end(), mutator.rng());
  for (int f = 0; f < dof && f < static_cast<int>(coordinates.size()); ++f) {
    m["free"].push_back({{"body", bodies[coordinates[static_cast<std::size_t>(f)].first].name},
                         {"coordinate", coordinates[static_cast<std::size_t>(f)].second},
                         {"velocity", uniform(-1, 1)}});
  }
  // Now and then a reference to nothing or a joint on itself.
  if (mutator.chance(0.05) && !m["joints"].empty()) m["joints"][0]["body2"] = m["joints"][0]["body1"];
  if (mutator.chance(0.05) && !m["drivers"].empty()) m["drivers"][0]["joint"] = "nowhere";
  return m;
}

TEST(MechanismFuzz, RandomMechanisms) {
  fuzz::Mutator mutator(fuzz::seed(23));
  int accepted = 0;
  for (int k = 0; k < fuzz::cases(400); ++k) {
    json input = tinySections(json::object());
    input["mechanism"] = randomMechanism(mutator, 1.0);
    const std::string text = input.dump();
    const Outcome outcome = expectConfigOrInvalidArgument([&] { return configFromJson(input); }, text, true);
    if (outcome.accepted) ++accepted;
    if (!outcome.accepted && !HasFailure())
      EXPECT_NE(outcome.message.find("mechanism"), std::string::npos) << outcome.message << "\n" << text;
    if (HasFailure()) return;
  }
  EXPECT_GT(accepted, 20);
  ::testing::Test::RecordProperty("accepted", accepted);
}

// Long lists: many bodies, joints and points. Refused or built, but quickly and without exhausting the
// memory.
TEST(MechanismFuzz, HugeLists) {
  const json seed = seeds().at(0);
  for (const std::size_t count : {std::size_t{100}, std::size_t{2000}}) {
    for (const char* list : kLists) {
      json input = tinySections(seed);
      json& m = input["mechanism"];
      json copies = json::array();
      const json prototype =
          m.contains(list) && !m[list].empty() ? m[list][0] : json::object({{"body", "crank"}});
      for (std::size_t i = 0; i < count; ++i) {
        json copy = prototype;
        if (copy.contains("name")) copy["name"] = std::string(list) + std::to_string(i);
        copies.push_back(copy);
      }
      m[list] = copies;
      expectConfigOrInvalidArgument([&] { return configFromJson(input); },
                                    std::string(list) + " x " + std::to_string(count), false);
    }
  }
  // A valid description with many bodies: each welded to the ground (a fixed joint, as many
  // constraints as coordinates), so the count of free coordinates stays right.
  // (400 of them took gigabytes and minutes before the first step: the dense constraint Jacobians in
  // dual numbers; the number of rigid bodies is now limited.)
  for (const std::size_t count : {std::size_t{10}, std::size_t{30}, std::size_t{31}, std::size_t{400}}) {
    json input = tinySections(seed);
    json& m = input["mechanism"];
    for (std::size_t i = 0; i < count; ++i) {
      const std::string name = "weight" + std::to_string(i);
      m["rigidBodies"].push_back(
          {{"name", name}, {"mass", 1.0}, {"position", {0.0, -1.0}}, {"points", {{"c", {0.0, 0.0}}}}});
      m["ground"]["points"][name] = {0.0, -1.0};
      m["joints"].push_back({{"name", "weld" + std::to_string(i)},
                             {"type", "fixed"},
                             {"body1", "ground"},
                             {"point1", name},
                             {"body2", name},
                             {"point2", "c"}});
    }
    const Outcome outcome = expectConfigOrInvalidArgument([&] { return configFromJson(input); },
                                                          std::to_string(count) + " welded bodies", true);
    const std::size_t bodies = count + 2;  // and the seed's crank and slider
    EXPECT_EQ(outcome.accepted, bodies <= static_cast<std::size_t>(mechanism::kMaxRigidBodies))
        << outcome.message;
    if (!outcome.accepted)
      EXPECT_NE(outcome.message.find("mechanism.rigidBodies lists"), std::string::npos) << outcome.message;
  }
}

// Driver speeds far beyond any motion: the position solve's continuation between two calls took
// ceil(distance / 0.25) Newton solves (1e9 rad/s: minutes for 0.02 s), converted to int from
// inf or beyond INT_MAX (undefined). Now a NumericalError saying so, at once.
TEST(MechanismFuzz, AbsurdDriverSpeedsFailFastByName) {
  for (const double speed : {1e9, 1e300, -1e300}) {
    json input = tinySections(seeds().at(4));  // a constant-speed driver
    input["mechanism"]["drivers"][0]["speed"] = speed;
    const Config config = configFromJson(input);
    const PistonRod rod(config);
    PistonRod::Request request;
    request.psi2 = false;
    request.psi2Gradient = false;
    try {
      rod.evaluate(rod.initialDesign(), request);
      ADD_FAILURE() << "speed " << speed << " evaluated";
    } catch (const NumericalError& e) {
      EXPECT_NE(std::string(e.what()).find("drivers or free coordinates move by"), std::string::npos)
          << e.what();
    }
  }
}

#ifdef HINDSIGHT_CLI_PATH
// The command-line tool: a refused description exits 2 with the same message on stderr, an accepted
// one 0 with psi1 (a handful of processes; the properties above are in-process).
TEST(MechanismFuzz, CliExitsTwoNamingTheFault) {
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/hindsight_fuzz_mechanism_cli.json";
  fuzz::Mutator mutator(fuzz::seed(24));
  int refused = 0;
  for (int k = 0; k < 200 && refused < 4; ++k) {
    json input = tinySections(seeds().at(mutator.below(5)));
    const std::string list = kLists[mutator.below(3)];
    json& element = input["mechanism"][list][0];
    const auto values = interestingValues();
    auto it = element.begin();
    std::advance(it, static_cast<long>(mutator.below(element.size())));
    element[it.key()] = mutator.pick(values);
    // The file as the tool reads it (a NaN is written as null).
    fuzz::writeText(path, input.dump(-1, ' ', false, json::error_handler_t::replace));
    std::string message;
    try {
      readConfigFile(path);
      continue;
    } catch (const std::invalid_argument& e) {
      message = e.what();
    }
    ++refused;
    const auto run = testing::runCli("evaluate --config " + path);
    EXPECT_EQ(run.exitCode, 2) << run.output;
    EXPECT_NE(run.output.find(message.substr(0, 60)), std::string::npos)
        << run.output << "\nexpected: " << message;
  }
  EXPECT_EQ(refused, 4);
}
#endif

}  // namespace
}  // namespace hindsight
