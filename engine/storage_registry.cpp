#include <hindsight/engine/storage_registry.h>

#include <charconv>
#include <limits>
#include <ostream>
#include <stdexcept>

namespace hindsight {

// ---- ScheduleCosts ----

ScheduleCosts ScheduleCosts::parse(const std::string& text, const std::string& field) {
  const std::string expected = field + " = '" + text +
                               "' must be four numbers uf:ub:wd:rd in [0, 1e30] (seconds of a forward step, "
                               "an adjoint step, a disk write and a disk read of one state), uf > 0";
  constexpr double kMaxCost = 1e30;
  double values[4];
  std::size_t position = 0;
  for (int i = 0; i < 4; ++i) {
    const std::size_t end = i < 3 ? text.find(':', position) : text.size();
    if (end == std::string::npos) throw std::invalid_argument(expected);
    const std::string part = text.substr(position, end - position);
    std::size_t used = 0;
    try {
      values[i] = std::stod(part, &used);
    } catch (const std::exception&) {
      throw std::invalid_argument(expected);
    }
    if (used != part.size() || !(values[i] >= 0.0 && values[i] <= kMaxCost))
      throw std::invalid_argument(expected);
    position = end + 1;
  }
  if (values[0] <= 0.0) throw std::invalid_argument(expected);
  return ScheduleCosts{values[0], values[1], values[2], values[3]};
}

std::string ScheduleCosts::text() const {
  // Shortest text that reads back to the same doubles (the spec round-trips).
  std::string out;
  for (double value : {forwardStep, adjointStep, diskWrite, diskRead}) {
    char buffer[32];
    const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
    if (!out.empty()) out += ':';
    out.append(buffer, result.ptr);
  }
  return out;
}

const char* levelName(StorageLevel level) { return level == StorageLevel::kRam ? "ram" : "disk"; }

// ---- rows ----

std::vector<std::string> StorageStrategyRow::keys() const {
  std::vector<std::string> names;
  names.reserve(doc.keys.size());
  for (const StorageKeyDoc& key : doc.keys) names.push_back(key.key);
  return names;
}

const StorageStrategyRow* findStorageStrategy(const std::vector<StorageStrategyRow>& rows,
                                              const std::string& name) {
  for (const StorageStrategyRow& row : rows) {
    if (row.name() == name) return &row;
  }
  return nullptr;
}

namespace {

std::string namesOf(const std::vector<StorageStrategyRow>& rows) {
  std::string names;
  for (const StorageStrategyRow& row : rows) names += (names.empty() ? "" : ", ") + row.name();
  return names;
}

}  // namespace

std::unique_ptr<TrajectoryStorage> createFromRows(const std::vector<StorageStrategyRow>& rows,
                                                  const std::string& text) {
  const StorageSpec spec = StorageSpec::parse(text);
  const StorageStrategyRow* row = findStorageStrategy(rows, spec.name());
  if (row == nullptr)
    throw std::invalid_argument("unknown storage strategy '" + spec.name() + "'; known: " + namesOf(rows));
  spec.requireKeysIn(row->keys());
  return row->create(spec);
}

// ---- predictions ----

namespace prediction {

std::int64_t checkedCount(UnsignedInt128 value, const std::string& what) {
  constexpr auto kMaxCount = static_cast<UnsignedInt128>(std::numeric_limits<std::int64_t>::max());
  if (value > kMaxCount) {
    // Decimal rendering of the 128-bit value (the message says by how much the range is exceeded).
    std::string digits;
    UnsignedInt128 rest = value;
    do {
      digits.insert(digits.begin(), static_cast<char>('0' + static_cast<int>(rest % 10)));
      rest /= 10;
    } while (rest != 0);
    throw std::invalid_argument(
        what + " = " + digits +
        " exceed the counters' range (2^63 - 1); lower --steps or raise the checkpoints");
  }
  return static_cast<std::int64_t>(value);
}

std::int64_t checkedProduct(std::int64_t a, std::int64_t b, const std::string& what) {
  if (a < 0 || b < 0) throw std::logic_error("checkedProduct: negative factor for " + what);
  return checkedCount(static_cast<UnsignedInt128>(a) * static_cast<UnsignedInt128>(b), what);
}

std::int64_t stepRecordBytes(const PredictionRequest& request, const std::string& name) {
  const UnsignedInt128 doubles =
      static_cast<UnsignedInt128>(request.stages - 1) * static_cast<UnsignedInt128>(request.stateBytes / 8) +
      static_cast<UnsignedInt128>(request.stages) * static_cast<UnsignedInt128>(request.stageDataBytes / 8);
  if (doubles > static_cast<UnsignedInt128>(std::numeric_limits<int>::max())) {
    throw std::invalid_argument(name + ".stages = 1: a step record of " + std::to_string(request.stages - 1) +
                                " stage states and " + std::to_string(request.stages) +
                                " rhs data exceeds the 2^31 - 1 doubles a run allows; lower --state-bytes, "
                                "--stage-bytes or --stages");
  }
  return static_cast<std::int64_t>(doubles) * 8;
}

std::int64_t stageRowDoubles(const PredictionRequest& request, bool stageRows, const std::string& name) {
  const std::int64_t n = request.stateBytes / 8;
  const std::int64_t rowDoubles = stageRows ? n + stepRecordBytes(request, name) / 8 : n;
  if (rowDoubles > std::numeric_limits<int>::max()) {
    throw std::invalid_argument(
        name + ".stages = 1: a row of the state and its step record (" + std::to_string(request.stages - 1) +
        " stage states and " + std::to_string(request.stages) + " rhs data) has " +
        std::to_string(rowDoubles) +
        " doubles, more than a run allows (2^31 - 1); lower --state-bytes, --stage-bytes or --stages");
  }
  return rowDoubles;
}

void ActionWriter::store(StorageLevel level, std::int64_t slot) {
  out << "store " << levelName(level) << ' ' << slot << '\n';
}
void ActionWriter::load(StorageLevel level, std::int64_t slot) {
  out << "load " << levelName(level) << ' ' << slot << '\n';
}
void ActionWriter::advance(std::int64_t from, std::int64_t to) {
  out << "advance " << from << ' ' << to << '\n';
}
void ActionWriter::loadWorking() { out << "load ram working\n"; }

void writeEveryStateActions(std::int64_t steps, StorageLevel level, std::ostream& out) {
  for (std::int64_t k = 0; k < steps; ++k)
    out << "record " << k << "\nstore " << levelName(level) << ' ' << k << '\n';
  for (std::int64_t e = steps - 1; e >= 0; --e)
    out << "restore " << e << "\nload " << levelName(level) << ' ' << e << '\n';
}

}  // namespace prediction

SchedulePrediction predictFromRows(const std::vector<StorageStrategyRow>& rows, const std::string& text,
                                   const PredictionRequest& request) {
  const StorageSpec spec = StorageSpec::parse(text);
  auto storage = createFromRows(rows, text);  // validates names, keys and values as a run would
  const StorageStrategyRow& row = *findStorageStrategy(rows, spec.name());
  if (row.predict == nullptr) {
    std::string predicted;
    for (const StorageStrategyRow& r : rows) {
      if (r.predict != nullptr) predicted += (predicted.empty() ? "" : ", ") + r.name();
    }
    throw std::invalid_argument("storage '" + spec.name() + "' is not predicted: " + row.notPredicted +
                                "; predicted are " + predicted);
  }
  SchedulePrediction p;
  p.strategy = storage->spec();
  p.steps = request.steps;
  p.stages = request.stages;
  p.forwardSteps = request.steps;
  if (request.costs != nullptr) p.costs = *request.costs;
  row.predict(*storage, spec, request, p);
  if (request.lowerBound && p.lowerBound < 0.0) {
    throw std::invalid_argument("--bound: '" + spec.name() +
                                "' has no lower bound to compare with; it is computed for multilevel plans "
                                "(H-Revolve's family of schedules on RAM and the levels below)");
  }
  // An adjoint step evaluates its S stages unless it has them stored (cams records, stages=1): S rhs for
  // every forward, recomputed and stage-recomputing adjoint step. For cams, steps - stepDataRestored are
  // its adjoint recomputations; for the others it is the adjoint steps without stored stage values.
  const UnsignedInt128 steps = static_cast<UnsignedInt128>(request.steps);
  p.rhsEvaluations =
      prediction::checkedCount(static_cast<UnsignedInt128>(request.stages) *
                                   (steps + static_cast<UnsignedInt128>(p.recomputedSteps) +
                                    static_cast<UnsignedInt128>(request.steps - p.stepDataRestored)),
                               "rhs evaluations");
  // The request's cost model, or the row's own (multilevel's costs=).
  const ScheduleCosts& model = p.costs;
  const double recomputation =
      static_cast<double>(p.recomputedSteps + p.adjointRecomputations) * model.forwardStep;
  p.scheduleCost = p.levels.empty() ? recomputation + static_cast<double>(p.diskWrites) * model.diskWrite +
                                          static_cast<double>(p.diskReads) * model.diskRead
                                    : recomputation;
  for (const LevelTraffic& level : p.levels)  // each level its own costs, in the order KLevelPlan sums them
    p.scheduleCost +=
        static_cast<double>(level.writes) * level.write + static_cast<double>(level.reads) * level.read;
  p.scheduleCost -= p.hiddenIoCost;
  p.totalCost = static_cast<double>(request.steps) * (model.forwardStep + model.adjointStep) + p.scheduleCost;
  return p;
}

}  // namespace hindsight
