#include <hindsight/problems/topopt/history_schema.h>
#include <hindsight/problems/topopt/results_file.h>
#include <hindsight/problems/topopt/run_fingerprint.h>

#include <hindsight/engine/hash.h>
#include <hindsight/storage/atomic_file.h>
#include <hindsight/storage/hdf5.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace {

/// The MMA state datasets in /state and the members they store.
const std::pair<const char*, Vector MmaState::*> kMmaVectors[] = {{"mma_xold1", &MmaState::xold1},
                                                                  {"mma_xold2", &MmaState::xold2},
                                                                  {"mma_low", &MmaState::low},
                                                                  {"mma_upp", &MmaState::upp}};

constexpr const char* kFormat = "hindsight-topology-results";
constexpr int kFormatVersion = 2;  // 2: Fletcher32 and content hashes
constexpr int kFirstChecksummedVersion = 2;
constexpr int kOldestReadableVersion = 1;  // 1: no checksums
constexpr const char* kHashAttribute = "content_hash";
constexpr const char* kRoot = "/";

[[noreturn]] void fail(const std::string& what) { throw hdf5::Error(what, {}); }

// FNV-1a over values in their stored form (little-endian int32 / float64), so that the hash is the
// same on every host and can be recomputed from the file by any reader.
class ContentHash {
 public:
  void add(std::uint64_t value, int bytes = 8) {
    unsigned char buffer[8];
    for (int b = 0; b < bytes; ++b) buffer[b] = static_cast<unsigned char>(value >> (8 * b));
    h_ = fnv1a(buffer, static_cast<std::size_t>(bytes), h_);
  }
  void add(double value) {
    std::uint64_t bits;
    std::memcpy(&bits, &value, sizeof bits);
    add(bits);
  }
  void add(int value) { add(static_cast<std::uint64_t>(static_cast<std::uint32_t>(value)), 4); }
  void add(const std::string& text) {
    add(static_cast<std::uint64_t>(text.size()));
    h_ = fnv1a(text.data(), text.size(), h_);
  }
  std::string text() const {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "fnv1a64:%016llx", static_cast<unsigned long long>(h_));
    return buffer;
  }

 private:
  std::uint64_t h_ = kFnv1aOffsetBasis;
};

template <typename T>
std::string datasetHash(const std::string& path, const std::vector<hsize_t>& dims, const T* values) {
  ContentHash hash;
  hash.add(path);
  hash.add(static_cast<std::uint64_t>(dims.size()));
  std::size_t count = 1;
  for (hsize_t d : dims) {
    hash.add(static_cast<std::uint64_t>(d));
    count *= static_cast<std::size_t>(d);
  }
  for (std::size_t i = 0; i < count; ++i) hash.add(values[i]);
  return hash.text();
}

// The run state's hash: the root attributes, mma_iteration and every dataset's hash in file order.
struct RootAttributes {
  std::string configuration;
  int completedIterations = 0;
  int finished = 0;
  int nx = 0;
  int ny = 0;
  int updates = 0;
  double objectiveScale = 0.0;
  int mmaIteration = 0;
  std::string fingerprint;  // empty: not stored (older files), then not hashed either
  int ranks = 0;
};

std::string rootHash(const RootAttributes& a,
                     const std::vector<std::pair<std::string, std::string>>& datasets) {
  ContentHash hash;
  hash.add(kFormatVersion);
  hash.add(a.configuration);
  for (int value : {a.completedIterations, a.finished, a.nx, a.ny, a.updates, a.mmaIteration})
    hash.add(value);
  hash.add(a.objectiveScale);
  if (!a.fingerprint.empty()) {
    hash.add(a.fingerprint);
    hash.add(a.ranks);
  }
  for (const auto& [path, datasetHashText] : datasets) {
    hash.add(path);
    hash.add(datasetHashText);
  }
  return hash.text();
}

// ---- writing ----

class Writer {
 public:
  // A dataset of `dims` holding `data`: chunked with an unlimited first dimension (chunked layout is
  // what the Fletcher32 filter needs; the unlimited dimension allows empty datasets), Fletcher32,
  // and its content hash as an attribute.
  template <typename T>
  void dataset(hid_t parent, const std::string& group, const char* name, hid_t memType, hid_t fileType,
               std::vector<hsize_t> dims, const T* data) {
    std::vector<hsize_t> maxDims = dims;
    maxDims[0] = H5S_UNLIMITED;
    std::vector<hsize_t> chunk = dims;
    chunk[0] = dims.size() == 1 ? std::min<hsize_t>(dims[0], 4096) : 1;
    for (hsize_t& size : chunk) size = std::max<hsize_t>(size, 1);
    const hdf5::Handle properties = hdf5::propertyList(H5P_DATASET_CREATE);
    hdf5::check(H5Pset_chunk(properties.get(), static_cast<int>(chunk.size()), chunk.data()), "chunking");
    hdf5::check(H5Pset_fletcher32(properties.get()), "the Fletcher32 filter");
    const hdf5::Handle dataset = hdf5::createDataset(parent, name, fileType, dims, maxDims, properties.get());
    hdf5::write(dataset.get(), memType, data);
    const std::string path = group + "/" + name;
    const std::string hash = datasetHash(path, dims, data);
    hdf5::writeStringAttribute(dataset.get(), kHashAttribute, hash);
    hashes.emplace_back(path, hash);
  }
  void doubles(hid_t parent, const std::string& group, const char* name, std::vector<hsize_t> dims,
               const double* data) {
    dataset(parent, group, name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, std::move(dims), data);
  }
  void ints(hid_t parent, const std::string& group, const char* name, const std::vector<int>& data) {
    dataset(parent, group, name, H5T_NATIVE_INT, H5T_STD_I32LE, {data.size()}, data.data());
  }

  std::vector<std::pair<std::string, std::string>> hashes;
};

void writeContents(hid_t file, const ResultsData& data) {
  const std::size_t rows = data.history.size();
  RootAttributes root;
  root.configuration = data.configurationJson;
  root.completedIterations = static_cast<int>(rows);
  root.finished = data.finished ? 1 : 0;
  root.nx = data.nx;
  root.ny = data.ny;
  root.updates = data.state.iteration;
  root.objectiveScale = data.state.objectiveScale;
  root.mmaIteration = data.state.mma.iteration;
  root.fingerprint = data.configurationFingerprint;
  root.ranks = data.ranks;
  hdf5::writeStringAttribute(file, "format", kFormat);
  hdf5::writeAttribute(file, "format_version", kFormatVersion);
  hdf5::writeStringAttribute(file, "configuration", root.configuration);
  hdf5::writeAttribute(file, "completed_iterations", root.completedIterations);
  hdf5::writeAttribute(file, "finished", root.finished);
  hdf5::writeAttribute(file, "nx", root.nx);
  hdf5::writeAttribute(file, "ny", root.ny);
  hdf5::writeAttribute(file, "updates", root.updates);
  hdf5::writeAttribute(file, "objective_scale", root.objectiveScale);
  if (!root.fingerprint.empty()) {
    hdf5::writeStringAttribute(file, "configuration_fingerprint", root.fingerprint);
    hdf5::writeAttribute(file, "ranks", root.ranks);
  }

  Writer writer;
  {
    const hdf5::Handle group = hdf5::createGroup(file, "history");
    // Every column of the schema (problems/topopt/history_schema.h), in its order.
    std::vector<int> integers(rows);
    std::vector<double> values(rows);
    for (const HistoryColumn& c : historyColumns()) {
      if (c.type == HistoryColumnType::int32) {
        for (std::size_t k = 0; k < rows; ++k) integers[k] = data.history[k].*(c.integer);
        writer.ints(group.get(), "/history", c.name, integers);
      } else {
        for (std::size_t k = 0; k < rows; ++k) values[k] = data.history[k].*(c.real);
        writer.doubles(group.get(), "/history", c.name, {rows}, values.data());
      }
    }
  }
  {
    const std::size_t cells = static_cast<std::size_t>(data.nx) * static_cast<std::size_t>(data.ny);
    std::vector<double> designs(rows * cells);
    for (std::size_t k = 0; k < rows; ++k) {
      std::copy(data.densities[k].data(), data.densities[k].data() + cells, designs.begin() + k * cells);
    }
    writer.doubles(file, "", "designs", {rows, static_cast<hsize_t>(data.ny), static_cast<hsize_t>(data.nx)},
                   designs.data());
  }
  {
    const hdf5::Handle group = hdf5::createGroup(file, "state");
    const auto n = static_cast<hsize_t>(data.state.design.size());
    writer.doubles(group.get(), "/state", "design", {n}, data.state.design.data());
    for (const auto& [name, member] : kMmaVectors) {
      writer.doubles(group.get(), "/state", name, {n}, (data.state.mma.*member).data());
    }
    // The end game's state: MMA's move limit, the objective at xold1 (problems/topopt/mma.h), the best
    // feasible objective so far, then the stopping rule's window of recent objectives, oldest first
    // (OptimizerState::bestObjective, recentObjectives).
    std::vector<double> endGame = {data.state.mma.moveLimit, data.state.mma.objective,
                                   data.state.bestObjective};
    endGame.insert(endGame.end(), data.state.recentObjectives.begin(), data.state.recentObjectives.end());
    writer.doubles(group.get(), "/state", "end_game", {static_cast<hsize_t>(endGame.size())}, endGame.data());
    // The end game's phase (OptimizerState::refining): 1 once the refinement has begun, else 0.
    const double refining = data.state.refining ? 1.0 : 0.0;
    writer.doubles(group.get(), "/state", "end_game_refining", {1}, &refining);
    if (data.state.bestDesign.size() > 0) {  // the best feasible design so far, once there is one
      writer.doubles(group.get(), "/state", "best_design",
                     {static_cast<hsize_t>(data.state.bestDesign.size())}, data.state.bestDesign.data());
    }
    hdf5::writeAttribute(group.get(), "mma_iteration", root.mmaIteration);
  }
  {
    const hdf5::Handle group = hdf5::createGroup(file, "final");
    // Column-major dofCount x modeCount is row-major modeCount x dofCount.
    writer.doubles(
        group.get(), "/final", "modes",
        {static_cast<hsize_t>(data.finalModes.cols()), static_cast<hsize_t>(data.finalModes.rows())},
        data.finalModes.data());
    writer.doubles(group.get(), "/final", "frequencies_hz", {data.finalFrequenciesHz.size()},
                   data.finalFrequenciesHz.data());
  }
  const std::size_t scenarios = static_cast<std::size_t>(data.state.scenarioScales.size());
  if (scenarios > 0) {
    // Runs with scenarios (problems/rod/scenarios.h) only; a file without them is unchanged.
    const hdf5::Handle group = hdf5::createGroup(file, "scenarios");
    std::vector<double> table(rows * scenarios);
    for (const auto& [name, member] : {std::pair<const char*, std::vector<double> IterationRecord::*>{
                                           "psi1", &IterationRecord::scenarioPsi1},
                                       {"psi2", &IterationRecord::scenarioPsi2}}) {
      for (std::size_t k = 0; k < rows; ++k) {
        const std::vector<double>& values = data.history[k].*member;
        if (values.size() != scenarios)
          throw std::invalid_argument("results: history row " + std::to_string(k) + " has " +
                                      std::to_string(values.size()) + " scenario values, expected " +
                                      std::to_string(scenarios));
        std::copy(values.begin(), values.end(), table.begin() + static_cast<std::ptrdiff_t>(k * scenarios));
      }
      writer.doubles(group.get(), "/scenarios", name, {rows, scenarios}, table.data());
    }
    writer.doubles(group.get(), "/scenarios", "objective_scale", {scenarios},
                   data.state.scenarioScales.data());
    writer.doubles(group.get(), "/scenarios", "bound", {static_cast<hsize_t>(data.state.bound.size())},
                   data.state.bound.data());
  }
  hdf5::writeStringAttribute(file, kHashAttribute, rootHash(root, writer.hashes));
}

// ---- reading and checking ----

std::string describe(double value) {
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

// An entry of a column as its type prints it: int32 columns as integers.
std::string describeEntry(const HistoryColumn& column, double value) {
  if (column.type == HistoryColumnType::int32) return std::to_string(static_cast<long long>(value));
  return describe(value);
}

// Reads the datasets and records one check per object: Fletcher32 (HDF5 refuses the read), the
// content hash, then plausibility. The data of a dataset that failed is not used by later checks.
class Reader {
 public:
  explicit Reader(ResultsVerification& verification)
      : verification_(verification), checksummed_(verification.checksummed) {}

  // Reads `name` below `parent` (whose path is `group`) with the expected shape; false when it
  // could not be read or its hash does not match.
  template <typename T>
  bool read(hid_t parent, const std::string& group, const char* name, hid_t memType,
            const std::vector<hsize_t>& dims, T* out) {
    const std::string path = group + "/" + name;
    ResultsCheck& check = add(path);
    try {
      hdf5::read(parent, name, memType, dims, out);
      if (checksummed_) {
        const hdf5::Handle dataset = hdf5::openDataset(parent, name);
        if (!hdf5::hasAttribute(dataset.get(), kHashAttribute)) {
          check.problem = "its attribute content_hash is missing";
        } else {
          const std::string stored = hdf5::readStringAttribute(dataset.get(), kHashAttribute);
          const std::string recomputed = datasetHash(path, dims, out);
          if (stored != recomputed) {
            check.problem = "its values do not match its content hash (stored " + stored + ", recomputed " +
                            recomputed + ")";
          }
          hashes_.emplace_back(path, stored);
        }
      }
    } catch (const hdf5::Error& e) {
      check.problem = e.what();  // names the dataset and HDF5's reason ("Fletcher32 checksum")
    }
    return check.problem.empty();
  }

  // The shape of a dataset that must exist and have `rank` dimensions.
  std::vector<hsize_t> shapeOf(hid_t parent, const char* name, std::size_t rank) {
    const std::vector<hsize_t> dims = hdf5::shape(hdf5::openDataset(parent, name).get());
    if (dims.size() != rank) {
      fail("dataset '" + hdf5::objectName(parent, name) + "' has " + std::to_string(dims.size()) +
           " dimensions, expected " + std::to_string(rank));
    }
    return dims;
  }

  ResultsCheck& add(const std::string& object) {
    verification_.checks.push_back({object, {}});
    return verification_.checks.back();
  }
  ResultsCheck* find(const std::string& object) {
    for (ResultsCheck& check : verification_.checks) {
      if (check.object == object) return &check;
    }
    return &add(object);
  }
  bool sound(const std::string& object) { return find(object)->problem.empty(); }
  // True when `object` was read (or checked) already; an optional dataset that is absent was not.
  bool has(const std::string& object) const {
    for (const ResultsCheck& check : verification_.checks) {
      if (check.object == object) return true;
    }
    return false;
  }
  // Records the first problem of an object.
  void problem(const std::string& object, const std::string& what) {
    ResultsCheck* check = find(object);
    if (check->problem.empty()) check->problem = what;
  }

  const std::vector<std::pair<std::string, std::string>>& hashes() const { return hashes_; }

 private:
  ResultsVerification& verification_;
  bool checksummed_;
  std::vector<std::pair<std::string, std::string>> hashes_;
};

// Plausibility of values of one object: finite and within [lower, upper]; the first offending entry
// is reported.
void checkRange(Reader& reader, const std::string& object, const double* values, std::size_t count,
                double lower, double upper, std::size_t skipFrom = static_cast<std::size_t>(-1)) {
  if (!reader.sound(object)) return;
  for (std::size_t i = 0; i < count && i < skipFrom; ++i) {
    if (!std::isfinite(values[i])) {
      reader.problem(object, "entry " + std::to_string(i) + " is " + describe(values[i]) + ", not finite");
      return;
    }
    if (!(values[i] >= lower && values[i] <= upper)) {
      reader.problem(object, "entry " + std::to_string(i) + " = " + describe(values[i]) + " is outside [" +
                                 describe(lower) + ", " + describe(upper) + "]");
      return;
    }
  }
}

void checkRange(Reader& reader, const std::string& object, const Vector& v, double lower, double upper) {
  checkRange(reader, object, v.data(), static_cast<std::size_t>(v.size()), lower, upper);
}

constexpr double kLargest = std::numeric_limits<double>::max();

// The restored state as the optimizer leaves it (docs/design.md §7, problems/topopt/mma.h).
void checkPlausibility(Reader& reader, const ResultsData& data, const RootAttributes& root) {
  double lower = 0.0;
  try {
    lower = configFromJson(nlohmann::json::parse(data.configurationJson)).rod.designLowerBound;
  } catch (const std::exception& e) {
    reader.problem(kRoot, std::string("the attribute configuration cannot be read: ") + e.what());
    return;
  }
  const std::size_t rows = data.history.size();
  const int updates = data.state.iteration;
  if (updates != static_cast<int>(rows) - (data.finished ? 1 : 0) || data.state.mma.iteration != updates) {
    reader.problem(kRoot, "inconsistent counters: " + std::to_string(rows) +
                              " completed iterations, finished " + std::to_string(root.finished) +
                              ", updates " + std::to_string(updates) + ", /state mma_iteration " +
                              std::to_string(data.state.mma.iteration));
  }
  if (rows > 0 && !(std::isfinite(data.state.objectiveScale) && data.state.objectiveScale > 0.0)) {
    reader.problem(
        kRoot, "objective_scale = " + describe(data.state.objectiveScale) + " is not positive and finite");
  }

  // The history, column by column as its schema says (problems/topopt/history_schema.h).
  std::vector<double> column(rows);
  for (const HistoryColumn& c : historyColumns()) {
    const std::string object = std::string("/history/") + c.name;
    if (!reader.has(object) || !reader.sound(object)) continue;  // absent (older file) or already failed
    for (std::size_t k = 0; k < rows; ++k) column[k] = historyValue(c, data.history[k]);
    if (c.rule == HistoryRule::rowIndex) {
      for (std::size_t k = 0; k < rows; ++k) {
        if (column[k] != static_cast<double>(k)) {
          reader.problem(object, "entry " + std::to_string(k) + " = " + describeEntry(c, column[k]) +
                                     ", expected " + std::to_string(k));
          break;
        }
      }
    } else if (c.type == HistoryColumnType::int32) {
      for (std::size_t k = 0; k < rows; ++k) {
        if (!(column[k] >= c.lower && column[k] <= c.upper)) {
          reader.problem(object, "entry " + std::to_string(k) + " = " + describeEntry(c, column[k]) +
                                     " is outside [" + describeEntry(c, c.lower) + ", " +
                                     describeEntry(c, c.upper) + "]");
          break;
        }
      }
    } else if (c.nan == HistoryNaN::allowed) {
      for (std::size_t k = 0; k < rows; ++k) {
        const double v = column[k];
        if (!std::isnan(v) && !(v >= c.lower && v <= c.upper)) {
          reader.problem(object, "entry " + std::to_string(k) + " = " + describe(v) + " is outside [" +
                                     describe(c.lower) + ", " + describe(c.upper) + "]");
          break;
        }
      }
    } else {
      // The final evaluation of a finished run made no update: its entry is not checked.
      const std::size_t skipFrom =
          c.nan == HistoryNaN::finalEvaluation && data.finished ? rows - 1 : static_cast<std::size_t>(-1);
      checkRange(reader, object, column.data(), rows, c.lower, c.upper, skipFrom);
    }
  }
  for (std::size_t k = 0; k < data.densities.size(); ++k) {
    if (!reader.sound("/designs")) break;
    const Vector& grid = data.densities[k];
    for (Eigen::Index e = 0; e < grid.size(); ++e) {
      if (!(std::isfinite(grid(e)) && grid(e) >= lower && grid(e) <= 1.0)) {
        reader.problem("/designs", "row " + std::to_string(k) + ", element " + std::to_string(e) + " = " +
                                       describe(grid(e)) + " is not in [" + describe(lower) + ", 1]");
        break;
      }
    }
  }

  const MmaState& mma = data.state.mma;
  checkRange(reader, "/state/design", data.state.design, lower, 1.0);
  if (data.state.bestDesign.size() > 0)
    checkRange(reader, "/state/best_design", data.state.bestDesign, lower, 1.0);
  // Before the first (second) update MMA's xold1 (xold2) are zeros, not designs.
  checkRange(reader, "/state/mma_xold1", mma.xold1, mma.iteration >= 1 ? lower : -kLargest,
             mma.iteration >= 1 ? 1.0 : kLargest);
  checkRange(reader, "/state/mma_xold2", mma.xold2, mma.iteration >= 2 ? lower : -kLargest,
             mma.iteration >= 2 ? 1.0 : kLargest);
  checkRange(reader, "/state/mma_low", mma.low, -kLargest, kLargest);
  checkRange(reader, "/state/mma_upp", mma.upp, -kLargest, kLargest);
  // Every update puts its asymptotes strictly around the design it started from (xold1) and the
  // design it produced (x): MMA's approximations are undefined at an asymptote.
  if (mma.iteration >= 1 && reader.sound("/state/mma_low") && reader.sound("/state/mma_upp")) {
    for (const auto& [object, x] :
         {std::pair<const char*, const Vector*>{"/state/mma_xold1", &mma.xold1},
          std::pair<const char*, const Vector*>{"/state/design", &data.state.design}}) {
      if (!reader.sound(object)) continue;
      for (Eigen::Index j = 0; j < x->size(); ++j) {
        if (!(mma.low(j) < (*x)(j))) {
          reader.problem("/state/mma_low", "entry " + std::to_string(j) + " = " + describe(mma.low(j)) +
                                               " is not below " + object + " = " + describe((*x)(j)));
          break;
        }
        if (!((*x)(j) < mma.upp(j))) {
          reader.problem("/state/mma_upp", "entry " + std::to_string(j) + " = " + describe(mma.upp(j)) +
                                               " is not above " + object + " = " + describe((*x)(j)));
          break;
        }
      }
    }
  }
  checkRange(reader, "/final/modes", data.finalModes.data(), static_cast<std::size_t>(data.finalModes.size()),
             -kLargest, kLargest);
  checkRange(reader, "/final/frequencies_hz", data.finalFrequenciesHz.data(), data.finalFrequenciesHz.size(),
             0.0, kLargest);
  if (data.finished != (data.finalModes.cols() > 0)) {
    reader.problem("/final/modes", std::to_string(data.finalModes.cols()) + " modes in a " +
                                       (data.finished ? "finished" : "unfinished") + " run");
  }
}

// Reads and checks everything; structural failures (not a results file, missing attributes or
// datasets, wrong ranks) throw hdf5::Error, everything else is recorded in `verification`.
// Sizes read from a file are only what the file claims. Before memory of that size is allocated, the
// dataset must fit in the file (datasets are stored uncompressed): a damaged file claiming 2^31
// iterations is refused, not allocated for.
void requireFitsInFile(hid_t file, hid_t parent, const char* name, const std::vector<hsize_t>& dims) {
  hsize_t fileSize = 0;
  if (H5Fget_filesize(file, &fileSize) < 0) fail("cannot read the file's size");
  hsize_t bytes = sizeof(double);
  for (const hsize_t d : dims) {
    if (d != 0 && bytes > fileSize / d)
      fail("dataset '" + hdf5::objectName(parent, name) + "' is larger than the file");
    bytes *= d;
  }
}

// A shape the root attributes give must be the dataset's own, and fit in the file.
void requireShape(hid_t file, hid_t parent, const char* name, const std::vector<hsize_t>& expected) {
  if (hdf5::shape(hdf5::openDataset(parent, name).get()) != expected) {
    fail("dataset '" + hdf5::objectName(parent, name) + "' does not have the shape the attributes give");
  }
  requireFitsInFile(file, parent, name, expected);
}

ResultsData readContents(hid_t file, ResultsVerification& verification) {
  if (hdf5::readStringAttribute(file, "format") != kFormat) fail("not a hindsight topology results file");
  const int version = hdf5::readIntAttribute(file, "format_version");
  if (version < kOldestReadableVersion || version > kFormatVersion)
    fail("format_version " + std::to_string(version) + " is not supported");
  verification.formatVersion = version;
  verification.checksummed = version >= kFirstChecksummedVersion;
  Reader reader(verification);
  reader.add(kRoot);

  ResultsData data;
  RootAttributes root;
  data.configurationJson = root.configuration = hdf5::readStringAttribute(file, "configuration");
  const int rowsSigned = root.completedIterations = hdf5::readIntAttribute(file, "completed_iterations");
  root.finished = hdf5::readIntAttribute(file, "finished");
  data.finished = root.finished != 0;
  data.nx = root.nx = hdf5::readIntAttribute(file, "nx");
  data.ny = root.ny = hdf5::readIntAttribute(file, "ny");
  data.state.iteration = root.updates = hdf5::readIntAttribute(file, "updates");
  data.state.objectiveScale = root.objectiveScale = hdf5::readDoubleAttribute(file, "objective_scale");
  if (hdf5::hasAttribute(file, "configuration_fingerprint")) {
    data.configurationFingerprint = root.fingerprint =
        hdf5::readStringAttribute(file, "configuration_fingerprint");
    data.ranks = root.ranks = hdf5::hasAttribute(file, "ranks") ? hdf5::readIntAttribute(file, "ranks") : 0;
    verification.configurationFingerprint = root.fingerprint;
    verification.ranks = root.ranks;
    std::string recomputed;
    try {
      recomputed = configurationFingerprint(data.configurationJson);
    } catch (const std::exception& e) {
      recomputed = std::string("none (") + e.what() + ")";
    }
    if (recomputed != root.fingerprint || root.ranks < 1) {
      reader.problem(kRoot, "configuration_fingerprint " + root.fingerprint + " (ranks " +
                                std::to_string(root.ranks) + ") does not match the stored configuration (" +
                                recomputed + "): the configuration is not the one the ranks agreed on");
    }
  }
  if (rowsSigned < 0 || data.nx < 1 || data.ny < 1 || data.state.iteration < 0 ||
      (root.finished != 0 && root.finished != 1))
    fail("inconsistent attributes");
  verification.completedIterations = rowsSigned;
  verification.finished = data.finished;
  const auto rows = static_cast<hsize_t>(rowsSigned);

  {
    const hdf5::Handle group = hdf5::openGroup(file, "history");
    // Every column's shape and extent before anything is allocated for K rows (K comes from an
    // attribute, which may claim 2^31 - 1) and before HDF5 reads it: a damaged layout of one column
    // (found by tests/fuzz) made HDF5 copy past its buffer instead of failing.
    for (const HistoryColumn& c : historyColumns()) {
      if (c.optional && !hdf5::exists(group.get(), c.name)) continue;  // written before the column existed
      requireShape(file, group.get(), c.name, {rows});
    }
    data.history.resize(rows);
    std::vector<int> integers(rows);
    std::vector<double> values(rows);
    for (const HistoryColumn& c : historyColumns()) {
      if (c.optional && !hdf5::exists(group.get(), c.name)) continue;
      if (c.type == HistoryColumnType::int32) {
        reader.read(group.get(), "/history", c.name, H5T_NATIVE_INT, {rows}, integers.data());
        for (hsize_t k = 0; k < rows; ++k) data.history[k].*(c.integer) = integers[k];
      } else {
        reader.read(group.get(), "/history", c.name, H5T_NATIVE_DOUBLE, {rows}, values.data());
        for (hsize_t k = 0; k < rows; ++k) data.history[k].*(c.real) = values[k];
      }
    }
    // A final record with a KKT residual computed an update it did not take: the stopping rule ended
    // the run there (the final evaluation of a run that used all its iterations has none).
    if (data.finished && rows > 0 && !std::isnan(data.history.back().kktResidual))
      data.history.back().converged = true;
  }
  {
    const auto nx = static_cast<hsize_t>(data.nx);
    const auto ny = static_cast<hsize_t>(data.ny);
    requireShape(file, file, "designs", {rows, ny, nx});
    std::vector<double> designs(rows * nx * ny);
    reader.read(file, "", "designs", H5T_NATIVE_DOUBLE, {rows, ny, nx}, designs.data());
    for (hsize_t k = 0; k < rows; ++k) {
      data.densities.push_back(
          Eigen::Map<const Vector>(designs.data() + k * nx * ny, static_cast<Eigen::Index>(nx * ny)));
    }
  }
  {
    const hdf5::Handle group = hdf5::openGroup(file, "state");
    const hsize_t size = reader.shapeOf(group.get(), "design", 1)[0];
    if (size < 1) fail("dataset '/state/design' is empty");
    requireFitsInFile(file, group.get(), "design", {size});
    data.state.design.setZero(static_cast<Eigen::Index>(size));
    reader.read(group.get(), "/state", "design", H5T_NATIVE_DOUBLE, {size}, data.state.design.data());
    for (const auto& [name, member] : kMmaVectors) {
      Vector& v = data.state.mma.*member;
      v.setZero(static_cast<Eigen::Index>(size));
      reader.read(group.get(), "/state", name, H5T_NATIVE_DOUBLE, {size}, v.data());
    }
    if (hdf5::exists(group.get(), "end_game")) {  // absent in files written before it existed
      const std::vector<hsize_t> dims = reader.shapeOf(group.get(), "end_game", 1);
      // Two entries in files written before the stopping rule kept its window.
      if (dims[0] != 2 && (dims[0] < 3 || dims[0] > 3 + OptimizerState::kObjectiveWindow)) {
        reader.problem("/state/end_game", "has " + std::to_string(dims[0]) + " entries, expected 2 or 3 to " +
                                              std::to_string(3 + OptimizerState::kObjectiveWindow));
      } else {
        std::vector<double> endGame(dims[0]);
        reader.read(group.get(), "/state", "end_game", H5T_NATIVE_DOUBLE, dims, endGame.data());
        data.state.mma.moveLimit = endGame[0];
        data.state.mma.objective = endGame[1];
        if (endGame.size() >= 3) {
          data.state.bestObjective = endGame[2];
          data.state.recentObjectives.assign(endGame.begin() + 3, endGame.end());
        }
        if (!(endGame[0] >= 0.0 && endGame[0] <= 1.0))
          reader.problem("/state/end_game", "move limit " + describe(endGame[0]) + " is outside [0, 1]");
      }
    }
    if (hdf5::exists(group.get(), "end_game_refining")) {  // absent in files written before the end game
      const std::vector<hsize_t> dims = reader.shapeOf(group.get(), "end_game_refining", 1);
      if (dims[0] != 1) {
        reader.problem("/state/end_game_refining", "has " + std::to_string(dims[0]) + " entries, expected 1");
      } else {
        double refining = 0.0;
        reader.read(group.get(), "/state", "end_game_refining", H5T_NATIVE_DOUBLE, dims, &refining);
        if (refining != 0.0 && refining != 1.0)
          reader.problem("/state/end_game_refining", "is " + describe(refining) + ", expected 0 or 1");
        data.state.refining = refining == 1.0;
      }
    }
    if (hdf5::exists(group.get(), "best_design")) {  // absent before the first feasible design
      const hsize_t best = reader.shapeOf(group.get(), "best_design", 1)[0];
      if (best != size) {
        reader.problem("/state/best_design",
                       "has " + std::to_string(best) + " entries, /state/design " + std::to_string(size));
      } else {
        data.state.bestDesign.setZero(static_cast<Eigen::Index>(size));
        reader.read(group.get(), "/state", "best_design", H5T_NATIVE_DOUBLE, {size},
                    data.state.bestDesign.data());
      }
    }
    data.state.mma.iteration = root.mmaIteration = hdf5::readIntAttribute(group.get(), "mma_iteration");
  }
  {
    const hdf5::Handle group = hdf5::openGroup(file, "final");
    const std::vector<hsize_t> dims = reader.shapeOf(group.get(), "modes", 2);
    requireFitsInFile(file, group.get(), "modes", dims);
    const hsize_t modeCount = dims[0];
    data.finalModes.setZero(static_cast<Eigen::Index>(dims[1]), static_cast<Eigen::Index>(modeCount));
    reader.read(group.get(), "/final", "modes", H5T_NATIVE_DOUBLE, dims, data.finalModes.data());
    data.finalFrequenciesHz.assign(modeCount, 0.0);
    reader.read(group.get(), "/final", "frequencies_hz", H5T_NATIVE_DOUBLE, {modeCount},
                data.finalFrequenciesHz.data());
  }
  if (hdf5::exists(file, "scenarios")) {
    const hdf5::Handle group = hdf5::openGroup(file, "scenarios");
    const hsize_t scenarios = reader.shapeOf(group.get(), "objective_scale", 1)[0];
    if (scenarios < 1) fail("dataset '/scenarios/objective_scale' is empty");
    requireFitsInFile(file, group.get(), "objective_scale", {scenarios});
    std::vector<double> table(rows * scenarios);
    for (const auto& [name, member] : {std::pair<const char*, std::vector<double> IterationRecord::*>{
                                           "psi1", &IterationRecord::scenarioPsi1},
                                       {"psi2", &IterationRecord::scenarioPsi2}}) {
      requireShape(file, group.get(), name, {rows, scenarios});
      reader.read(group.get(), "/scenarios", name, H5T_NATIVE_DOUBLE, {rows, scenarios}, table.data());
      for (hsize_t k = 0; k < rows; ++k)
        data.history[k].*member =
            std::vector<double>(table.begin() + static_cast<std::ptrdiff_t>(k * scenarios),
                                table.begin() + static_cast<std::ptrdiff_t>((k + 1) * scenarios));
    }
    data.state.scenarioScales.setZero(static_cast<Eigen::Index>(scenarios));
    reader.read(group.get(), "/scenarios", "objective_scale", H5T_NATIVE_DOUBLE, {scenarios},
                data.state.scenarioScales.data());
    const hsize_t bound = reader.shapeOf(group.get(), "bound", 1)[0];
    if (bound != 0 && bound != 4) fail("dataset '/scenarios/bound' must have 0 or 4 entries");
    data.state.bound.setZero(static_cast<Eigen::Index>(bound));
    reader.read(group.get(), "/scenarios", "bound", H5T_NATIVE_DOUBLE, {bound}, data.state.bound.data());
    checkRange(reader, "/scenarios/objective_scale", data.state.scenarioScales,
               std::numeric_limits<double>::min(), kLargest);
  }
  if (verification.checksummed) {
    // Over the stored dataset hashes: a mismatch here means the root attributes changed (a changed
    // dataset is already reported under its own name).
    if (!hdf5::hasAttribute(file, kHashAttribute)) {
      reader.problem(kRoot, "its attribute content_hash is missing");
    } else if (reader.hashes().size() == verification.checks.size() - 1) {
      const std::string stored = hdf5::readStringAttribute(file, kHashAttribute);
      const std::string recomputed = rootHash(root, reader.hashes());
      if (stored != recomputed) {
        reader.problem(kRoot,
                       "the attributes (configuration, counters, mma_iteration) do not match the run "
                       "state's content hash (stored " +
                           stored + ", recomputed " + recomputed + ")");
      }
    }
  }
  checkPlausibility(reader, data, root);
  data.checksummed = verification.checksummed;
  return data;
}

// What the HDF5 layer and the checks above throw, as the StorageError this file's interface promises.
[[noreturn]] void rethrow(const hdf5::Error& e, const std::string& path) {
  throw StorageError("results file: " + std::string(e.what()), path);
}

std::string corruptedObject(const std::string& object) {
  return object == kRoot ? "the attributes of '/' are corrupted" : "dataset '" + object + "' is corrupted";
}

}  // namespace

const ResultsCheck* ResultsVerification::firstProblem() const {
  for (const ResultsCheck& check : checks) {
    if (!check.problem.empty()) return &check;
  }
  return nullptr;
}

void writeResultsFile(const std::string& path, const ResultsData& data) {
  const std::size_t cells = static_cast<std::size_t>(data.nx) * static_cast<std::size_t>(data.ny);
  if (data.nx < 1 || data.ny < 1) throw std::invalid_argument("results: nx and ny must be >= 1");
  if (data.densities.size() != data.history.size()) {
    throw std::invalid_argument("results: " + std::to_string(data.densities.size()) + " density grids for " +
                                std::to_string(data.history.size()) + " history entries");
  }
  for (const Vector& grid : data.densities) {
    if (static_cast<std::size_t>(grid.size()) != cells)
      throw std::invalid_argument("results: density grid size");
  }
  const Eigen::Index n = data.state.design.size();
  if (n < 1 || data.state.mma.xold1.size() != n || data.state.mma.xold2.size() != n ||
      data.state.mma.low.size() != n || data.state.mma.upp.size() != n) {
    throw std::invalid_argument("results: state vectors must all have the design's length (>= 1)");
  }
  if (static_cast<std::size_t>(data.finalModes.cols()) != data.finalFrequenciesHz.size()) {
    throw std::invalid_argument("results: one frequency per final mode");
  }

  const hdf5::ErrorSilencer quiet;
  // Built in memory and written by the atomic stream write: HDF5 never writes to the disk itself
  // (see hdf5::createMemoryFile), so a full disk is an ordinary failed write.
  std::vector<unsigned char> image;
  try {
    hdf5::Handle file = hdf5::createMemoryFile(path);
    writeContents(file.get(), data);
    image = hdf5::fileImage(file.get());
    hdf5::closeFile(file);
  } catch (const hdf5::Error& e) {
    rethrow(e, path);
  }
  writeBytesAtomically(path, image.data(), image.size(), "the results file");
}

ResultsVerification verifyResultsFile(const std::string& path) {
  const hdf5::ErrorSilencer quiet;
  ResultsVerification verification;
  try {
    const hdf5::Handle file = hdf5::openFileReadOnly(path, "the results file");
    readContents(file.get(), verification);
  } catch (const hdf5::Error& e) {
    rethrow(e, path);
  }
  return verification;
}

ResultsData readResultsFile(const std::string& path) {
  const hdf5::ErrorSilencer quiet;
  ResultsVerification verification;
  ResultsData data;
  try {
    const hdf5::Handle file = hdf5::openFileReadOnly(path, "the results file");
    data = readContents(file.get(), verification);
  } catch (const hdf5::Error& e) {
    rethrow(e, path);
  }
  if (const ResultsCheck* bad = verification.firstProblem()) {
    throw StorageError("results file: " + corruptedObject(bad->object) + ": " + bad->problem +
                           "; refusing to use it (`hindsight verify` lists every dataset)",
                       path);
  }
  return data;
}

std::string readResultsConfiguration(const std::string& path) {
  return readResultsFile(path).configurationJson;
}

}  // namespace hindsight
