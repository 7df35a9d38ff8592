// hindsight._hindsight: the C++ side of the Python module `hindsight` (python/hindsight/__init__.py
// wraps it; docs/guides/python.md). Everything goes through the library's own code paths: configurations
// through configFromJson/applySetting/applyFlag (the CLI's validation and messages), storage specs
// through the factory, the rod through PistonRod::evaluate as `hindsight evaluate` calls it, the
// optimization through OptimizationRun as `hindsight optimize` runs it, results through
// readResultsFile with all its checks.
//
// Errors: std::invalid_argument -> ValueError (pybind11's own translation), NumericalError ->
// hindsight.NumericalError, StorageError -> hindsight.StorageError (both RuntimeError subclasses),
// other std::exception -> RuntimeError; the message is e.what(), as the CLI prints it.
//
// The GIL is released while C++ simulates (rod evaluation, optimization); meanwhile the engine's
// interrupt poll (engine/interrupt.h) re-acquires it every ~50 ms on the main thread and runs
// PyErr_CheckSignals, so Ctrl-C raises KeyboardInterrupt out of a long evaluation. A problem written
// in Python keeps the GIL (its callbacks are Python code, which sees Ctrl-C itself).
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/dense_blocking.h>
#include <hindsight/engine/interrupt.h>
#include <hindsight/engine/problem.h>
#include <hindsight/problems/app/config.h>
#include <hindsight/problems/app/full_order_evaluation.h>
#include <hindsight/problems/app/gradient_routes.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/problems/rod/design_io.h>
#include <hindsight/problems/rod/full_order_rod.h>
#include <hindsight/problems/topopt/history_schema.h>
#include <hindsight/problems/topopt/optimization_run.h>
#include <hindsight/problems/topopt/results_file.h>
#include <hindsight/storage/checkpoint_actions.h>
#include <hindsight/storage/checkpoint_stream.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_docs.h>
#include <hindsight/storage/storage_factory.h>

#include <pybind11/iostream.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <signal.h>  // sigaction (POSIX)
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

namespace py = pybind11;

namespace hindsight::python {
namespace {

// ---- Interruption ------------------------------------------------------------------------------

std::thread::id mainThread;
std::atomic<std::int64_t> nextPollNanoseconds{0};

std::int64_t nowNanoseconds() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

/// The engine's interrupt poll while the GIL is released: at most every 50 ms, on the main thread only
/// (Python runs signal handlers there), take the GIL and let Python run its handlers; a pending
/// exception (KeyboardInterrupt) is thrown as error_already_set, which unwinds the computation.
/// Once the main thread has seen a KeyboardInterrupt, or SIGINT arrived while the main thread was not
/// polling (it waits for the worker threads of scenarios evaluated in parallel, inside TBB, while only
/// a worker still simulates), the polls of the other threads throw this, translated to
/// KeyboardInterrupt, so that no thread keeps simulating after Ctrl-C.
struct InterruptedOnTheMainThread final : std::exception {
  const char* what() const noexcept override { return "interrupted (KeyboardInterrupt)"; }
};
std::atomic<bool> interrupted{false};
/// Set by the SIGINT handler below (async-signal-safe: a lock-free atomic store).
std::atomic<bool> sigintReceived{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the SIGINT handler stores to this atomic");
struct sigaction pythonSigint {};
bool sigintWrapped = false;

/// Chained in front of Python's own SIGINT handler while a computation runs: records the signal for
/// the worker threads' polls, then lets Python's handler trip its flag as usual, so that the main
/// thread's next PyErr_CheckSignals raises KeyboardInterrupt exactly once.
void onSigint(int signal, siginfo_t* info, void* context) {
  sigintReceived.store(true, std::memory_order_relaxed);
  if ((pythonSigint.sa_flags & SA_SIGINFO) != 0) {
    pythonSigint.sa_sigaction(signal, info, context);
  } else if (pythonSigint.sa_handler != SIG_DFL && pythonSigint.sa_handler != SIG_IGN) {
    pythonSigint.sa_handler(signal);
  }
}

void pollPythonSignals() {
  const bool onMainThread = std::this_thread::get_id() == mainThread;
  if (!onMainThread) {
    if (interrupted.load(std::memory_order_relaxed) || sigintReceived.load(std::memory_order_relaxed)) {
      interrupted.store(true, std::memory_order_relaxed);
      throw InterruptedOnTheMainThread();
    }
    return;
  }
  const std::int64_t now = nowNanoseconds();
  if (now < nextPollNanoseconds.load(std::memory_order_relaxed)) return;
  nextPollNanoseconds.store(now + 50'000'000, std::memory_order_relaxed);
  py::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() != 0) {
    interrupted.store(true, std::memory_order_relaxed);
    throw py::error_already_set();
  }
}

/// Installs the poll while at least one computation runs: Python threads may run several at once (the
/// GIL is released), and the last one to finish removes it. The SIGINT wrapper is installed only
/// in front of a handler Python installed (a process that ignores SIGINT keeps ignoring it).
class PollInstallation {
 public:
  PollInstallation() {
    const std::lock_guard<std::mutex> lock(mutex());
    if (count()++ == 0) {
      nextPollNanoseconds = 0;
      interrupted = false;
      sigintReceived = false;
      setInterruptPoll(&pollPythonSignals);
      struct sigaction current {};
      if (sigaction(SIGINT, nullptr, &current) == 0 &&
          ((current.sa_flags & SA_SIGINFO) != 0 ||
           (current.sa_handler != SIG_DFL && current.sa_handler != SIG_IGN))) {
        struct sigaction wrapper {};
        wrapper.sa_sigaction = &onSigint;
        wrapper.sa_flags = SA_SIGINFO | (current.sa_flags & SA_RESTART);
        sigemptyset(&wrapper.sa_mask);
        pythonSigint = current;
        sigintWrapped = sigaction(SIGINT, &wrapper, nullptr) == 0;
      }
    }
  }
  ~PollInstallation() {
    const std::lock_guard<std::mutex> lock(mutex());
    if (--count() == 0) {
      setInterruptPoll(nullptr);
      if (sigintWrapped) sigaction(SIGINT, &pythonSigint, nullptr);
      sigintWrapped = false;
    }
  }
  PollInstallation(const PollInstallation&) = delete;
  PollInstallation& operator=(const PollInstallation&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static int& count() {
    static int n = 0;
    return n;
  }
};

/// Releases the GIL and installs the poll for the scope of a C++ computation.
class Simulating {
 private:
  PollInstallation poll_;           // installed before the GIL is released,
  py::gil_scoped_release release_;  // re-acquired before the poll is removed
};

// ---- Conversions -------------------------------------------------------------------------------

/// A configuration value from Python, converted directly (not through json.dumps, which turned a NaN
/// into a JSON parse error and refused NumPy scalars): None, bool, str, int and float including NumPy's
/// scalars (a NaN or infinity reaches the field's own check, which names the field and its range),
/// lists and tuples, dicts with string keys. A complex number, bytes or any other object is refused
/// naming `where` and the type (a complex crank speed must not lose its imaginary part silently).
nlohmann::json toCppJson(const py::handle& value, const std::string& where = "config") {
  PyObject* object = value.ptr();
  if (value.is_none()) return nullptr;
  const std::string typeName = py::str(py::type::of(value).attr("__name__"));
  if (PyBool_Check(object) || typeName == "bool_") return value.cast<bool>();
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::isinstance<py::dict>(value)) {
    nlohmann::json out = nlohmann::json::object();
    for (const auto& [key, item] : value.cast<py::dict>()) {
      if (!py::isinstance<py::str>(key))
        throw std::invalid_argument(where + ": key " + std::string(py::repr(key)) + " must be a string");
      const std::string name = key.cast<std::string>();
      out[name] = toCppJson(item, where + "." + name);
    }
    return out;
  }
  if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    nlohmann::json out = nlohmann::json::array();
    std::size_t index = 0;
    for (const py::handle item : value)
      out.push_back(toCppJson(item, where + "[" + std::to_string(index++) + "]"));
    return out;
  }
  if (PyComplex_Check(object) || typeName.rfind("complex", 0) == 0) {
    throw std::invalid_argument(where + " = " + std::string(py::repr(value)) +
                                " must be a real number, not complex");
  }
  // int and NumPy integers; an ndarray has __index__ too but refuses it unless it holds one integer.
  const py::object integer =
      PyIndex_Check(object) ? py::reinterpret_steal<py::object>(PyNumber_Index(object)) : py::object();
  if (!integer && PyErr_Occurred()) PyErr_Clear();
  if (integer) {
    const long long small = PyLong_AsLongLong(integer.ptr());
    if (!(small == -1 && PyErr_Occurred())) return small;
    PyErr_Clear();
    const unsigned long long large = PyLong_AsUnsignedLongLong(integer.ptr());
    if (!(large == static_cast<unsigned long long>(-1) && PyErr_Occurred())) return large;
    PyErr_Clear();
    throw std::invalid_argument(where + " = " + std::string(py::repr(value)) +
                                " is outside the 64-bit integer range");
  }
  if (PyFloat_Check(object) || typeName.rfind("float", 0) == 0) return value.cast<double>();  // NumPy floats
  throw std::invalid_argument(where + " = " + std::string(py::repr(value)) + ": a " + typeName +
                              " is not a configuration value (None, bool, number, str, list or dict)");
}

using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// `x` as an array of doubles, refusing what a silent cast would get wrong: complex values (the
/// imaginary part dropped), strings ("0.5" parsed as a number), objects and booleans.
DoubleArray realArray(const py::handle& x, const std::string& name) {
  const py::array array = py::array::ensure(x);
  if (!array) throw std::invalid_argument(name + " must be an array of real numbers");
  const char kind = array.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw std::invalid_argument(name + " must hold real numbers (a float or int array), not dtype " +
                                std::string(py::str(array.dtype())));
  }
  return DoubleArray::ensure(array);
}

py::object toPython(const nlohmann::json& value) {
  return py::module_::import("json").attr("loads")(value.dump());
}

/// A NumPy array owning `values` (moved, no copy), with the given shape.
py::array_t<double> ownedArray(std::vector<double>&& values, std::vector<py::ssize_t> shape) {
  auto* owned = new std::vector<double>(std::move(values));
  py::capsule free(owned, [](void* p) { delete static_cast<std::vector<double>*>(p); });
  return py::array_t<double>(shape, owned->data(), free);
}

py::array_t<double> vectorArray(const Vector& v) {
  return ownedArray(std::vector<double>(v.data(), v.data() + v.size()), {v.size()});
}

py::array_t<double> gridArray(const rod::RodConfig& config, const Vector& field, double interfaceValue) {
  const std::vector<std::size_t> shape = designGridShape(config);  // (ny, nx), the solid's (nz, ny, nx)
  return ownedArray(designToGrid(config, field, interfaceValue),
                    std::vector<py::ssize_t>(shape.begin(), shape.end()));
}

/// The configuration from a dict (the JSON file's content), a path to a JSON file or None, then the
/// overrides: "section.field" = value, or section = {field: value, ...}. The overrides are merged into
/// the JSON and the whole is read once by configFromJson (the reader of --config files: same checks,
/// messages naming the field), so their order does not matter (rod.endTime with rod.rampTime).
Config makeConfig(const py::object& config, const py::dict& overrides) {
  nlohmann::json json = nlohmann::json::object();
  if (py::isinstance<py::str>(config)) {
    json = toJson(readConfigFile(config.cast<std::string>()));
  } else if (!config.is_none()) {
    if (!py::isinstance<py::dict>(config))
      throw std::invalid_argument("config must be a dict (the JSON configuration), a file path or None");
    json = toCppJson(config);
  }
  const auto assign = [&](const std::string& key, const py::handle& value) {
    const auto dot = key.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == key.size() ||
        key.find('.', dot + 1) != std::string::npos)
      throw std::invalid_argument("override '" + key + "' must have the form section.field");
    nlohmann::json& section = json[key.substr(0, dot)];
    if (section.is_null()) section = nlohmann::json::object();
    if (!section.is_object())
      throw std::invalid_argument("config section '" + key.substr(0, dot) + "' must be a dict");
    section[key.substr(dot + 1)] = toCppJson(value, key);
  };
  for (const auto& [keyObject, value] : overrides) {
    const std::string key = py::str(keyObject);
    if (key.find('.') != std::string::npos) {
      assign(key, value);
    } else if (py::isinstance<py::dict>(value)) {
      for (const auto& [field, fieldValue] : value.cast<py::dict>())
        assign(key + "." + std::string(py::str(field)), fieldValue);
    } else {
      throw std::invalid_argument("override '" + key +
                                  "' must be a section given as a dict (rod={'modeCount': 8}) or a "
                                  "'section.field' key");
    }
  }
  return configFromJson(json);
}

// ---- The rod -----------------------------------------------------------------------------------

class PyPistonRod {
 public:
  explicit PyPistonRod(Config config) : rod_(std::move(config)) {}

  const Config& config() const { return rod_.config(); }
  py::object configDict() const { return toPython(toJson(config())); }

  Vector design(const py::handle& input) const {
    const DoubleArray x = realArray(input, "design x");
    const rod::RodConfig& c = config().rod;
    const std::vector<std::size_t> shape = designGridShape(c);
    bool same = x.ndim() == static_cast<py::ssize_t>(shape.size());
    for (std::size_t a = 0; same && a < shape.size(); ++a)
      same = x.shape(static_cast<py::ssize_t>(a)) == static_cast<py::ssize_t>(shape[a]);
    if (same) return gridToDesign(c, x.data(), "design x");
    if (c.isSolid())
      throw std::invalid_argument(
          "design x must have shape (nz, ny, nx) = (" + std::to_string(c.elementsThroughThickness) + ", " +
          std::to_string(c.elementsThroughHeight) + ", " + std::to_string(c.elementsAlongLength) +
          "): rod.elementsThroughThickness x rod.elementsThroughHeight x "
          "rod.elementsAlongLength, end columns 1");
    throw std::invalid_argument("design x must have shape (ny, nx) = (" +
                                std::to_string(c.elementsThroughHeight) + ", " +
                                std::to_string(c.elementsAlongLength) +
                                "): rod.elementsThroughHeight x "
                                "rod.elementsAlongLength, end columns 1");
  }

  py::array_t<double> x0() const { return gridArray(config().rod, rod_.initialDesign(), 1.0); }

  py::dict evaluate(const py::object& x, bool gradient, const py::object& storage, const py::object& adjoint,
                    const py::object& integrator, bool psi2Wanted) const {
    // The per-call choices go through the CLI's flag path (same validation, messages naming the key).
    Config config = rod_.config();
    if (!storage.is_none()) applyFlag(config, "storage", "simulation.storage", storage.cast<std::string>());
    if (!adjoint.is_none()) applyFlag(config, "adjoint", "simulation.adjoint", adjoint.cast<std::string>());
    if (!integrator.is_none())
      applyFlag(config, "integrator", "simulation.integrator", integrator.cast<std::string>());
    const PistonRod rod(config);
    const Vector design = this->design(x);
    if (config.simulation.model == RodModel::Full) return evaluateFullOrder(config, design, gradient);
    // As `hindsight evaluate`: psi2 needs fixed steps.
    const bool psi2 = psi2Wanted && !config.simulation.adaptive;
    PistonRodEvaluation result;
    {
      Simulating simulating;
      result = rod.evaluate(design, {gradient, psi2, gradient && psi2});
    }
    const rod::RodConfig& c = config.rod;
    py::dict out;
    out["psi1"] = result.psi1;
    out["psi2"] = psi2 ? py::object(py::float_(result.psi2)) : py::object(py::none());
    out["volume_fraction"] = result.volumeFraction;
    out["frequencies_hz"] = ownedArray(std::vector<double>(result.frequenciesHz),
                                       {static_cast<py::ssize_t>(result.frequenciesHz.size())});
    out["gap_ratio"] = result.gapRatio;
    out["warning"] = result.warning;
    out["dpsi1_dx"] = gradient ? py::object(gridArray(c, result.dpsi1, 0.0)) : py::object(py::none());
    out["dpsi2_dx"] = gradient && psi2 ? py::object(gridArray(c, result.dpsi2, 0.0)) : py::object(py::none());
    out["dvolume_dx"] =
        result.dvolume.size() > 0 ? py::object(gridArray(c, result.dvolume, 0.0)) : py::object(py::none());
    // The same derivatives over the design variables (the order of rod.design_variables), for
    // optimizers that work on the variables (scipy.optimize).
    out["dpsi1_dv"] = gradient ? py::object(vectorArray(result.dpsi1)) : py::object(py::none());
    out["dpsi2_dv"] = gradient && psi2 ? py::object(vectorArray(result.dpsi2)) : py::object(py::none());
    out["dvolume_dv"] =
        result.dvolume.size() > 0 ? py::object(vectorArray(result.dvolume)) : py::object(py::none());
    out["summary"] = toPython(summaryToJson(result.summary));
    py::dict seconds;
    seconds["model"] = result.modelSeconds;
    seconds["simulation"] = result.simulationSeconds;
    seconds["chain"] = result.chainSeconds;
    seconds["esl"] = result.eslSeconds;
    out["seconds"] = seconds;
    out["model"] = "reduced";
    return out;
  }

 private:
  /// The full-order model of docs/design.md §9, as `hindsight evaluate --model full`: psi1, its
  /// gradient and the volume fraction (no psi2, no modes).
  static py::dict evaluateFullOrder(const Config& config, const Vector& design, bool gradient) {
    rod::FullOrderRodEvaluation result;
    {
      Simulating simulating;
      result = rod::evaluateFullOrderRod(config, design, gradient);
    }
    const rod::RodConfig& c = config.rod;
    py::dict out;
    out["model"] = "full";
    out["psi1"] = result.psi1;
    out["psi2"] = py::none();
    out["volume_fraction"] = result.volumeFraction;
    out["frequencies_hz"] = py::none();
    out["dpsi1_dx"] = gradient ? py::object(gridArray(c, result.dpsi1, 0.0)) : py::object(py::none());
    out["dpsi2_dx"] = py::none();
    out["dvolume_dx"] =
        result.dvolume.size() > 0 ? py::object(gridArray(c, result.dvolume, 0.0)) : py::object(py::none());
    out["dpsi1_dv"] = gradient ? py::object(vectorArray(result.dpsi1)) : py::object(py::none());
    out["dpsi2_dv"] = py::none();
    out["dvolume_dv"] =
        result.dvolume.size() > 0 ? py::object(vectorArray(result.dvolume)) : py::object(py::none());
    out["state_size"] = result.stateSize;
    out["omega_max"] = result.omegaMax;
    out["coupling"] = config.simulation.fullOrderCoupling;
    out["summary"] = toPython(summaryToJson(result.summary));
    py::dict seconds;
    seconds["model"] = result.modelSeconds;
    seconds["simulation"] = result.simulationSeconds;
    out["seconds"] = seconds;
    return out;
  }

  PistonRod rod_;
};

// ---- Results and optimization ------------------------------------------------------------------

/// One record as the callback of optimize() sees it: every column of the history's schema
/// (problems/topopt/history_schema.h) by its name, and whether the stopping rule held there.
py::dict recordDict(const IterationRecord& r) {
  py::dict d;
  for (const HistoryColumn& c : historyColumns()) {
    if (c.type == HistoryColumnType::int32) {
      d[c.name] = r.*(c.integer);
    } else {
      d[c.name] = r.*(c.real);
    }
  }
  d["converged"] = r.converged;
  return d;
}

/// The history as columns: every column of the schema, named as /history/<column> in results.h5, as
/// int32 or float64 arrays as the file stores them.
py::dict historyColumnArrays(const std::vector<IterationRecord>& history) {
  const auto rows = static_cast<py::ssize_t>(history.size());
  py::dict d;
  for (const HistoryColumn& c : historyColumns()) {
    if (c.type == HistoryColumnType::int32) {
      py::array_t<std::int32_t> values(rows);
      auto view = values.mutable_unchecked<1>();
      for (py::ssize_t k = 0; k < rows; ++k) view(k) = history[static_cast<std::size_t>(k)].*(c.integer);
      d[c.name] = values;
    } else {
      std::vector<double> values;
      values.reserve(history.size());
      for (const IterationRecord& r : history) values.push_back(r.*(c.real));
      d[c.name] = ownedArray(std::move(values), {rows});
    }
  }
  return d;
}

/// The schema itself, for Python (hindsight.history_columns()).
py::list historySchema() {
  py::list out;
  for (const HistoryColumn& c : historyColumns()) {
    py::dict entry;
    entry["name"] = c.name;
    entry["type"] = c.type == HistoryColumnType::int32 ? "int32" : "float64";
    entry["unit"] = c.unit;
    entry["description"] = c.description;
    entry["reproducible"] = c.reproducible;
    entry["optional"] = c.optional;
    out.append(entry);
  }
  return out;
}

py::dict readResults(const std::string& path) {
  ResultsData data;
  {
    py::gil_scoped_release release;
    data = readResultsFile(path);
  }
  py::dict out;
  out["history"] = historyColumnArrays(data.history);
  std::vector<double> designs;
  designs.reserve(data.densities.size() * static_cast<std::size_t>(data.nx) * data.ny);
  for (const Vector& grid : data.densities)
    designs.insert(designs.end(), grid.data(), grid.data() + grid.size());
  out["designs"] =
      ownedArray(std::move(designs), {static_cast<py::ssize_t>(data.densities.size()), data.ny, data.nx});
  out["configuration"] = py::module_::import("json").attr("loads")(data.configurationJson);
  out["nx"] = data.nx;
  out["ny"] = data.ny;
  out["finished"] = data.finished;
  out["checksummed"] = data.checksummed;
  out["next_design"] = vectorArray(data.state.design);
  out["final_frequencies_hz"] = data.finalFrequenciesHz;
  // dofCount x modeCount in memory; the file's /final/modes is modeCount x dofCount (row = mode).
  const Matrix modes = data.finalModes.transpose();
  out["final_modes"] =
      ownedArray(std::vector<double>(modes.data(), modes.data() + modes.size()),
                 {static_cast<py::ssize_t>(modes.cols()), static_cast<py::ssize_t>(modes.rows())});
  if (!data.history.empty() && !data.history.front().scenarioPsi1.empty()) {
    // Runs with scenarios (/scenarios in the file): every scenario's psi per iteration, K x S, as
    // `hindsight plot` draws them ("scenarios" is the name the shared plotting code reads), and psi_s(x0).
    const auto table = [&data](std::vector<double> IterationRecord::*member) {
      const std::size_t scenarios = (data.history.front().*member).size();
      std::vector<double> values;
      values.reserve(data.history.size() * scenarios);
      for (const IterationRecord& record : data.history) {
        values.insert(values.end(), (record.*member).begin(), (record.*member).end());
      }
      return ownedArray(std::move(values),
                        {static_cast<py::ssize_t>(data.history.size()), static_cast<py::ssize_t>(scenarios)});
    };
    out["scenarios"] = table(&IterationRecord::scenarioPsi1);
    out["scenario_psi2"] = table(&IterationRecord::scenarioPsi2);
    out["scenario_objective_scale"] = vectorArray(data.state.scenarioScales);
  }
  return out;
}

/// Stops an optimization from its callback (the callback returned a false value other than None); not
/// an error.
struct StopRequested {};

py::dict optimize(const Config& config, const std::string& out, bool resume, bool force,
                  const py::object& callback, bool verbose) {
  const std::string stored = (std::filesystem::path(out) / "results.h5").string();
  if (resume && !force && !std::filesystem::exists(stored)) {
    // As the CLI (exit 2): a mistyped directory must not start a fresh run of the configured length.
    throw std::invalid_argument("resume: there is no " + stored +
                                " to continue (check out=, or start a new run without resume=True)");
  }
  OptimizationRunOptions options;
  options.outputDirectory = out;
  options.resume = resume;
  options.force = force;
  if (!callback.is_none()) {
    options.afterCommit = [&callback](const IterationRecord& record) {
      py::gil_scoped_acquire gil;
      const py::object answer = callback(recordDict(record));
      // Any false value but None stops (False, 0, np.False_); None -- no return statement -- continues.
      if (!answer.is_none()) {
        const int truth = PyObject_IsTrue(answer.ptr());
        if (truth < 0) throw py::error_already_set();
        if (truth == 0) throw StopRequested{};
      }
    };
  }
  OptimizationRun run(config, options);  // every input check, before any evaluation
  bool stopped = false;
  {
    // Progress lines go to Python's sys.stdout (a notebook shows them), or nowhere.
    std::ostream discard(nullptr);  // no buffer: output is dropped
    py::object stdoutObject = py::module_::import("sys").attr("stdout");
    py::detail::pythonbuf buffer(
        stdoutObject);  // what py::scoped_ostream_redirect uses; takes the GIL to write
    std::ostream progress(&buffer);
    Simulating simulating;
    try {
      run.run(verbose ? progress : static_cast<std::ostream&>(discard));
    } catch (const StopRequested&) {
      stopped = true;
    }
    progress.flush();
  }
  py::dict result;
  result["results_path"] = run.resultsPath();
  result["stopped_by_callback"] = stopped;
  return result;
}

// ---- A problem written in Python ----------------------------------------------------------------

/// Adapts a Python object with the methods of docs/guides/python.md to hindsight::Problem. Called with the
/// GIL held (hindsight.gradient does not release it for a Python problem). Arrays handed to Python
/// are copies (the engine's buffers are reused); results are checked for shape.
class PythonProblem final : public Problem {
 public:
  explicit PythonProblem(py::object object) : object_(std::move(object)) {
    stateSize_ = attribute("state_size").cast<int>();
    parameterSize_ = attribute("parameter_size").cast<int>();
    if (stateSize_ < 1) throw std::invalid_argument("problem.state_size must be >= 1");
    if (parameterSize_ < 0) throw std::invalid_argument("problem.parameter_size must be >= 0");
    name_ = py::hasattr(object_, "name")
                ? py::str(object_.attr("name")).cast<std::string>()
                : py::str(py::type::of(object_).attr("__name__")).cast<std::string>();
    hasJacobian_ = has("rhs_jacobian");
    hasStateVjp_ = has("rhs_state_vjp");
    if (!hasJacobian_ && !hasStateVjp_)
      throw std::invalid_argument("problem needs rhs_jacobian(t, z, p) or rhs_state_vjp(t, z, p, w)");
    for (const char* method : {"initial_state", "rhs", "rhs_parameter_vjp", "integrand",
                               "integrand_state_gradient", "integrand_parameter_gradient"}) {
      if (!has(method)) throw std::invalid_argument(std::string("problem needs a method ") + method);
    }
    hasTerminal_ = has("terminal");
    if (hasTerminal_ && !has("terminal_gradient"))
      throw std::invalid_argument(
          "problem.terminal needs problem.terminal_gradient(z, p) -> (dphi/dz, dphi/dp)");
    hasInitialVjp_ = has("initial_state_vjp");
    // Bound methods looked up once: a getattr per call would cost more than the copies of z and p.
    const auto lookup = [&](const char* name) {
      return has(name) ? py::object(object_.attr(name)) : py::object(py::none());
    };
    methods_.initial_state = lookup("initial_state");
    methods_.initial_state_vjp = lookup("initial_state_vjp");
    methods_.rhs = lookup("rhs");
    methods_.rhs_jacobian = lookup("rhs_jacobian");
    methods_.rhs_state_vjp = lookup("rhs_state_vjp");
    methods_.rhs_parameter_vjp = lookup("rhs_parameter_vjp");
    methods_.integrand = lookup("integrand");
    methods_.integrand_state_gradient = lookup("integrand_state_gradient");
    methods_.integrand_parameter_gradient = lookup("integrand_parameter_gradient");
    methods_.terminal = lookup("terminal");
    methods_.terminal_gradient = lookup("terminal_gradient");
  }

  std::string name() const override { return name_; }
  int stateSize() const override { return stateSize_; }
  int parameterSize() const override { return parameterSize_; }
  bool hasDenseJacobian() const override { return hasJacobian_; }
  bool hasStateVjp() const override { return hasStateVjp_; }

  void initialState(ConstVectorRef p, VectorRef z0) const override {
    copyInto("initial_state", methods_.initial_state(array(p)), z0);
  }
  void addInitialStateVjp(ConstVectorRef p, ConstVectorRef lambda0, VectorRef gradient) const override {
    if (!hasInitialVjp_) return;
    addInto("initial_state_vjp", methods_.initial_state_vjp(array(p), array(lambda0)), gradient, 1.0);
  }
  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
    copyInto("rhs", methods_.rhs(t, array(z), array(p)), f);
  }
  void rhsJacobian(double t, ConstVectorRef z, ConstVectorRef p, MatrixRef jacobian,
                   ProblemWorkspace*) const override {
    const auto result =
        checked("rhs_jacobian", methods_.rhs_jacobian(t, array(z), array(p)), stateSize_, stateSize_);
    const auto view = result.unchecked<2>();
    for (int i = 0; i < stateSize_; ++i)
      for (int j = 0; j < stateSize_; ++j) jacobian(i, j) = view(i, j);
  }
  void rhsStateVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                   ProblemWorkspace*) const override {
    if (!hasStateVjp_) {  // from the Jacobian
      Matrix jacobian(stateSize_, stateSize_);
      rhsJacobian(t, z, p, jacobian, nullptr);
      out.noalias() = jacobian.transpose() * w;
      return;
    }
    copyInto("rhs_state_vjp", methods_.rhs_state_vjp(t, array(z), array(p), array(w)), out);
  }
  void addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace*) const override {
    addInto("rhs_parameter_vjp", methods_.rhs_parameter_vjp(t, array(z), array(p), array(w)), out, 1.0);
  }
  double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace*) const override {
    return methods_.integrand(t, array(z), array(p)).cast<double>();
  }
  void addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale, VectorRef out,
                                 ProblemWorkspace*) const override {
    addInto("integrand_state_gradient", methods_.integrand_state_gradient(t, array(z), array(p)), out, scale);
  }
  void addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                     VectorRef out, ProblemWorkspace*) const override {
    addInto("integrand_parameter_gradient", methods_.integrand_parameter_gradient(t, array(z), array(p)), out,
            scale);
  }
  double terminal(ConstVectorRef z, ConstVectorRef p) const override {
    return hasTerminal_ ? methods_.terminal(array(z), array(p)).cast<double>() : 0.0;
  }
  void addTerminalGradient(ConstVectorRef z, ConstVectorRef p, VectorRef gz, VectorRef gp) const override {
    if (!hasTerminal_) return;
    const py::tuple both = methods_.terminal_gradient(array(z), array(p));
    if (both.size() != 2)
      throw std::invalid_argument("problem.terminal_gradient must return (dphi/dz, dphi/dp)");
    addInto("terminal_gradient[0]", both[0], gz, 1.0);
    addInto("terminal_gradient[1]", both[1], gp, 1.0);
  }

 private:
  /// An optional method is present when the attribute exists and is not None.
  bool has(const char* name) const { return py::hasattr(object_, name) && !object_.attr(name).is_none(); }
  py::object attribute(const char* name) const {
    if (!py::hasattr(object_, name))
      throw std::invalid_argument(std::string("problem needs an attribute ") + name);
    return object_.attr(name);
  }
  static py::array_t<double> array(ConstVectorRef v) {
    return py::array_t<double>(v.size(), v.data());  // a copy: the engine reuses its buffers
  }
  using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;
  static Array checked(const char* method, const py::handle& value, py::ssize_t rows, py::ssize_t cols = -1) {
    Array a = Array::ensure(value);
    const bool ok = a && (cols < 0 ? (a.ndim() == 1 && a.shape(0) == rows)
                                   : (a.ndim() == 2 && a.shape(0) == rows && a.shape(1) == cols));
    if (!ok) {
      throw std::invalid_argument("problem." + std::string(method) + " must return an array of shape (" +
                                  std::to_string(rows) +
                                  (cols < 0 ? ",)" : ", " + std::to_string(cols) + ")") + ", got " +
                                  py::repr(value).cast<std::string>().substr(0, 80));
    }
    return a;
  }
  static void copyInto(const char* method, const py::handle& value, VectorRef out) {
    const Array a = checked(method, value, out.size());
    for (Eigen::Index i = 0; i < out.size(); ++i) out(i) = a.data()[i];
  }
  static void addInto(const char* method, const py::handle& value, VectorRef out, double scale) {
    const Array a = checked(method, value, out.size());
    for (Eigen::Index i = 0; i < out.size(); ++i) out(i) += scale * a.data()[i];
  }

  py::object object_;
  struct Methods {
    py::object initial_state, initial_state_vjp, rhs, rhs_jacobian, rhs_state_vjp, rhs_parameter_vjp,
        integrand, integrand_state_gradient, integrand_parameter_gradient, terminal, terminal_gradient;
  } methods_;
  std::string name_;
  int stateSize_ = 0, parameterSize_ = 0;
  bool hasJacobian_ = false, hasStateVjp_ = false, hasTerminal_ = false, hasInitialVjp_ = false;
};

/// The solver options of IntegratorOptions (engine/integrator.h) that Python passes by keyword, with
/// Python's names; max_steps also bounds CVODES (CvodesOptions::maxSteps). Values are checked by
/// IntegratorOptions::validate (its messages are put in Python's words by hindsight/__init__.py).
void applySolverOptions(const py::dict& solver, GradientOptions& options) {
  for (const auto& item : solver) {
    const std::string key = py::str(item.first).cast<std::string>();
    const py::handle value = item.second;
    if (key == "min_step") {
      options.integrator.minStep = value.cast<double>();
    } else if (key == "max_step") {
      options.integrator.maxStep = value.cast<double>();
    } else if (key == "max_steps") {
      options.integrator.maxSteps = value.cast<std::int64_t>();
      options.cvodes.maxSteps = options.integrator.maxSteps;
    } else if (key == "newton_tolerance") {
      options.integrator.newtonTolerance = value.cast<double>();
    } else if (key == "newton_max_iterations") {
      options.integrator.newtonMaxIterations = value.cast<int>();
    } else if (key == "rho_infinity") {
      options.integrator.rhoInfinity = value.cast<double>();
    } else {
      throw std::invalid_argument("unknown solver option '" + key +
                                  "'; known: min_step, max_step, max_steps, newton_tolerance, "
                                  "newton_max_iterations, rho_infinity");
    }
  }
}

/// atol: a float (the scalar tolerance) or a 1-D float64 array of one tolerance per state (the
/// integrator's and CVODES' per-component tolerances; their sizes are checked against the problem).
GradientOptions gradientOptions(const std::string& integrator, double step, double t0, double t1,
                                const std::string& storage, const std::string& adjoint, bool adaptive,
                                double rtol, const py::object& atol, const py::dict& solver) {
  GradientOptions options;
  options.adjoint = parseAdjointMethod(adjoint);
  options.integrator.method = integrator;
  options.integrator.step = step;
  options.integrator.t0 = t0;
  options.integrator.t1 = t1;
  options.integrator.adaptive = adaptive;
  options.integrator.relativeTolerance = rtol;
  options.storage = storage;
  options.cvodes.relativeTolerance = rtol;
  if (py::isinstance<py::float_>(atol)) {
    options.integrator.absoluteTolerance = options.cvodes.absoluteTolerance = atol.cast<double>();
  } else {
    const auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(atol);
    if (!values || values.ndim() != 1) throw std::invalid_argument("atol must be a float or a 1-D array");
    options.integrator.absoluteTolerances.assign(values.data(), values.data() + values.shape(0));
    options.cvodes.absoluteTolerances = options.integrator.absoluteTolerances;
  }
  applySolverOptions(solver, options);
  return options;
}

py::dict gradientDict(const GradientResult& result) {
  py::dict out;
  out["psi"] = result.objective;
  out["gradient"] = vectorArray(result.gradient);
  out["times"] =
      ownedArray(std::vector<double>(result.times), {static_cast<py::ssize_t>(result.times.size())});
  out["summary"] = toPython(summaryToJson(result.summary));
  return out;
}

Vector parameterVector(const py::array_t<double, py::array::c_style | py::array::forcecast>& p, int size,
                       const std::string& what) {
  if (p.ndim() != 1 || p.shape(0) != size) {
    throw std::invalid_argument("p must be a 1-D array of " + what + " = " + std::to_string(size) +
                                " values");
  }
  return Eigen::Map<const Vector>(p.data(), p.shape(0));
}

/// The C++ problems of problems/classic by name.
std::unique_ptr<Problem> classicProblem(const std::string& name) {
  if (name == "oscillator") return std::make_unique<Oscillator>();
  if (name == "decay") return std::make_unique<ExponentialDecay>();
  if (name == "pendulum") return std::make_unique<Pendulum>();
  throw std::invalid_argument("classic problem '" + name +
                              "' is not offered; known: oscillator, decay, pendulum");
}

/// The C++ problems of problems/classic by name, for comparisons with a problem written in Python.
py::dict classicGradient(const std::string& name,
                         const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                         const GradientOptions& options) {
  const std::unique_ptr<Problem> problem = classicProblem(name);
  const Vector parameters = parameterVector(p, problem->parameterSize(), "the problem's parameter count");
  GradientResult result;
  {
    Simulating simulating;
    result = computeGradientByMethod(*problem, parameters, options);
  }
  return gradientDict(result);
}

py::dict gradient(const py::object& problem,
                  const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                  const GradientOptions& options) {
  const PythonProblem adapter(problem);
  const Vector parameters = parameterVector(p, adapter.parameterSize(), "problem.parameter_size");
  return gradientDict(computeGradientByMethod(adapter, parameters, options));
}

struct StopSimulation {};

/// The forward sweep only (engine/adjoint.h, simulate): psi, and the grid with the state at every grid
/// point (collect), the right-hand side there too (derivatives, for hindsight.simulate's Hermite
/// interpolation at output times), and observer(t, z) called at every grid point; an observer
/// returning a false value other than None stops the simulation there (psi is then None). With
/// `release`, the GIL is released meanwhile (a C++ problem) and taken for the observer.
py::dict simulateProblem(const Problem& problem, const Vector& p, const IntegratorOptions& options,
                         const py::object& observer, bool collect, bool derivatives, bool release) {
  const int n = problem.stateSize();
  std::vector<double> times, states, rates;
  Vector f(n);
  const std::unique_ptr<ProblemWorkspace> workspace = derivatives ? problem.createWorkspaceFor(p) : nullptr;
  const bool observed = !observer.is_none();
  const StateObserver record = [&](std::int64_t, double t, ConstVectorRef z) {
    if (collect) {
      times.push_back(t);
      states.insert(states.end(), z.data(), z.data() + n);
    }
    if (derivatives) {
      problem.rhs(t, z, p, f, workspace.get());
      rates.insert(rates.end(), f.data(), f.data() + n);
    }
    if (observed) {
      std::optional<py::gil_scoped_acquire> gil;
      if (release) gil.emplace();
      const py::object answer = observer(t, py::array_t<double>(n, z.data()));
      if (!answer.is_none()) {
        const int truth = PyObject_IsTrue(answer.ptr());
        if (truth < 0) throw py::error_already_set();
        if (truth == 0) throw StopSimulation{};
      }
    }
  };
  std::optional<ForwardResult> result;
  bool stopped = false;
  try {
    if (release) {
      Simulating simulating;
      result = simulate(problem, p, options, record);
    } else {
      result = simulate(problem, p, options, record);
    }
  } catch (const StopSimulation&) {
    stopped = true;
  }
  const auto rows = static_cast<py::ssize_t>(times.size());
  py::dict out;
  out["psi"] = result ? py::object(py::float_(result->objective)) : py::object(py::none());
  out["stopped_by_observer"] = stopped;
  if (collect) {
    out["times"] = ownedArray(std::move(times), {rows});
    out["states"] = ownedArray(std::move(states), {rows, n});
  }
  if (derivatives) out["rates"] = ownedArray(std::move(rates), {rows, n});
  out["summary"] = result ? toPython(summaryToJson(result->summary)) : py::object(py::none());
  return out;
}

py::dict simulateAny(const py::object& problem,
                     const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                     const GradientOptions& options, const py::object& observer, bool collect,
                     bool derivatives) {
  if (py::isinstance<py::str>(problem)) {
    const std::unique_ptr<Problem> classic = classicProblem(problem.cast<std::string>());
    const Vector parameters = parameterVector(p, classic->parameterSize(), "the problem's parameter count");
    return simulateProblem(*classic, parameters, options.integrator, observer, collect, derivatives, true);
  }
  const PythonProblem adapter(problem);
  const Vector parameters = parameterVector(p, adapter.parameterSize(), "problem.parameter_size");
  return simulateProblem(adapter, parameters, options.integrator, observer, collect, derivatives, false);
}

py::list storageSpecs() {
  py::list out;
  for (const std::string& name : storageStrategyNames()) {
    py::dict entry;
    entry["name"] = name;
    const StorageStrategyDoc* doc = findStorageStrategyDoc(name);
    py::dict keys;
    for (const std::string& key : storageStrategyKeys(name)) {
      std::string text;
      if (doc != nullptr) {
        for (const StorageKeyDoc& k : doc->keys) {
          if (k.key == key) text = k.doc;
        }
      }
      keys[py::str(key)] = text;
    }
    entry["key_docs"] = keys;
    entry["summary"] = doc != nullptr ? doc->summary : std::string();
    entry["exact"] = doc != nullptr ? py::object(py::bool_(doc->exact)) : py::object(py::none());
    entry["example"] = doc != nullptr ? doc->example : name;
    // The registry's prediction: whether `hindsight.schedule` predicts the strategy, and why not.
    const StorageStrategyRow* row = findStorageStrategy(storageStrategies(), name);
    entry["predicted"] = row != nullptr && row->predict != nullptr;
    entry["not_predicted"] = row != nullptr && row->predict == nullptr ? row->notPredicted : std::string();
    out.append(entry);
  }
  return out;
}

}  // namespace
}  // namespace hindsight::python

PYBIND11_MODULE(_hindsight, m) {
  using namespace hindsight;
  using namespace hindsight::python;
  m.doc() = "C++ side of the hindsight Python module; use the package `hindsight`.";
  mainThread = std::this_thread::get_id();
  // A malformed HINDSIGHT_EMULATE_CPU_CACHES fails the import (ImportError naming it), as it stops the tool.
  emulatedCacheSizesFromSetting(std::getenv("HINDSIGHT_EMULATE_CPU_CACHES"));
  // This module keeps its own copy of Eigen's cache sizes (hidden symbols): what it plans with, and
  // what the CPU reported, for the reproducibility test (engine/dense_blocking.h).
  m.def("_dense_blocking", [] {
    const CacheSizes used = denseBlockingCacheSizes(), reported = cpuReportedCacheSizes();
    py::dict out;
    out["used"] = py::make_tuple(used.l1, used.l2, used.l3);
    out["cpu"] = py::make_tuple(reported.l1, reported.l2, reported.l3);
    return out;
  });

  // RuntimeError subclasses; registered after pybind11's own translators, so they win for these types.
  py::register_exception<NumericalError>(m, "NumericalError", PyExc_RuntimeError).attr("__doc__") =
      "A numerical failure of a simulation (Newton divergence, step-size underflow, non-finite state).";
  py::register_exception<StorageError>(m, "StorageError", PyExc_RuntimeError).attr("__doc__") =
      "A trajectory-storage or results-file failure (unwritable, full, corrupted, over budget).";

  py::register_exception_translator([](std::exception_ptr error) {
    try {
      if (error) std::rethrow_exception(error);
    } catch (const InterruptedOnTheMainThread&) {
      // Python's handler tripped its flag when SIGINT came while only a worker polled: running the
      // handlers now raises that KeyboardInterrupt here, once, instead of a second time later.
      if (PyErr_CheckSignals() == 0 && PyErr_Occurred() == nullptr) PyErr_SetNone(PyExc_KeyboardInterrupt);
    }
  });

  m.attr("__version__") = version();

  py::class_<PyPistonRod>(m, "PistonRod")
      .def(py::init([](const py::object& config, const py::kwargs& overrides) {
             return PyPistonRod(makeConfig(config, overrides));
           }),
           py::arg("config") = py::none())
      .def_property_readonly("config", &PyPistonRod::configDict)
      .def_property_readonly("x0", &PyPistonRod::x0)
      .def_property_readonly("design_count",
                             [](const PyPistonRod& r) { return r.config().rod.designCount(); })
      .def_property_readonly("shape",
                             [](const PyPistonRod& r) {
                               const rod::RodConfig& c = r.config().rod;
                               if (c.isSolid())
                                 return py::make_tuple(c.elementsThroughThickness, c.elementsThroughHeight,
                                                       c.elementsAlongLength);
                               return py::make_tuple(c.elementsThroughHeight, c.elementsAlongLength);
                             })
      .def("design_variables",
           [](const PyPistonRod& r, const py::object& x) { return vectorArray(r.design(x)); })
      .def(
          "design_grid",
          [](const PyPistonRod& r, const py::array_t<double, py::array::c_style | py::array::forcecast>& v,
             double interfaceValue) {
            const Vector values = Eigen::Map<const Vector>(v.data(), v.size());
            return gridArray(r.config().rod, values, interfaceValue);
          },
          py::arg("values"), py::arg("interface_value") = 1.0)
      .def("_evaluate", &PyPistonRod::evaluate, py::arg("x"), py::arg("gradient"), py::arg("storage"),
           py::arg("adjoint"), py::arg("integrator"), py::arg("psi2"));

  m.def(
      "_make_config",
      [](const py::object& config, const py::kwargs& overrides) {
        return toPython(toJson(makeConfig(config, overrides)));
      },
      py::arg("config") = py::none());
  m.def("_optimize", [](const py::object& config, const std::string& out, bool resume, bool force,
                        const py::object& callback, bool verbose, const py::kwargs& overrides) {
    return optimize(makeConfig(config, overrides), out, resume, force, callback, verbose);
  });
  m.def("_read_results", &readResults);
  m.def("_history_columns", &historySchema);
  using PArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
  m.def("_gradient",
        [](const py::object& problem, const PArray& p, const std::string& integrator, double step, double t0,
           double t1, const std::string& storage, const std::string& adjoint, bool adaptive, double rtol,
           const py::object& atol, const py::dict& solver) {
          return gradient(
              problem, p,
              gradientOptions(integrator, step, t0, t1, storage, adjoint, adaptive, rtol, atol, solver));
        });
  m.def("_classic_gradient", [](const std::string& name, const PArray& p, const std::string& integrator,
                                double step, double t0, double t1, const std::string& storage,
                                const std::string& adjoint, bool adaptive, double rtol,
                                const py::object& atol, const py::dict& solver) {
    return classicGradient(
        name, p, gradientOptions(integrator, step, t0, t1, storage, adjoint, adaptive, rtol, atol, solver));
  });
  m.def("_simulate", [](const py::object& problem, const PArray& p, const std::string& integrator,
                        double step, double t0, double t1, bool adaptive, double rtol, const py::object& atol,
                        const py::dict& solver, const py::object& observer, bool collect, bool derivatives) {
    return simulateAny(
        problem, p,
        gradientOptions(integrator, step, t0, t1, "full", "discrete", adaptive, rtol, atol, solver), observer,
        collect, derivatives);
  });
  m.def("_storage_specs", &storageSpecs);
  m.def("_schedule", [](const std::string& spec, std::int64_t steps, std::int64_t stateBytes, int stages,
                        const std::string& costs, bool actions, std::int64_t stageBytes, bool bound) {
    // The model-free prediction of `hindsight schedule` (storage/schedule.h): the same code and checks.
    std::optional<ScheduleCosts> parsed;
    if (!costs.empty()) parsed = ScheduleCosts::parse(costs, "costs");
    SchedulePrediction p;
    std::string stream;
    {
      const Simulating computing;  // a plan may take minutes: Ctrl-C interrupts it (engine/interrupt.h)
      p = predictSchedule(spec, steps, stateBytes, stages, parsed ? &*parsed : nullptr, stageBytes, bound);
      if (actions) {
        std::ostringstream out;
        writeScheduleActions(spec, steps, stateBytes, stages, parsed ? &*parsed : nullptr, out, stageBytes);
        stream = out.str();
      }
    }
    py::dict d = toPython(scheduleToJson(p, stateBytes)).cast<py::dict>();
    if (actions) d["actions"] = stream;
    return d;
  });
  // storage/checkpoint_stream.h: the stream handed out one action at a time (per action a tuple: kind, n0,
  // n1, write_ics, write_adj_deps, storage, clear_adj_deps, from, to; None after EndReverse), with
  // checkpoint_schedules' schedule state.
  py::class_<CheckpointStream>(m, "_CheckpointStream")
      .def("next",
           [](CheckpointStream& stream) -> py::object {
             // Each action is O(1) amortized (the plans are made when the stream is opened): no poll
             // installation per action, which would double the cost of draining a stream.
             CheckpointAction a;
             if (!stream.next(&a)) return py::none();
             return py::make_tuple(static_cast<int>(a.kind), a.n0, a.n1, a.writeIcs, a.writeAdjDeps,
                                   checkpointStorageName(a.storage), a.clearAdjDeps,
                                   checkpointStorageName(a.from), checkpointStorageName(a.to));
           })
      .def_property_readonly("n", &CheckpointStream::n)
      .def_property_readonly("r", &CheckpointStream::r)
      .def_property_readonly("max_n", &CheckpointStream::maxN)
      .def_property_readonly("is_exhausted", &CheckpointStream::isExhausted)
      .def_property_readonly("restart_data",
                             [](const CheckpointStream& stream) {
                               return stream.restartData() == RestartData::kState ? "state" : "interval";
                             })
      .def("finalize", &CheckpointStream::finalize);
  m.def("_open_checkpoint_stream", [](const std::string& spec, std::int64_t steps, std::int64_t stateBytes,
                                      int stages, const std::string& costs, bool intervals) {
    std::optional<ScheduleCosts> parsed;
    if (!costs.empty()) parsed = ScheduleCosts::parse(costs, "costs");
    const Simulating computing;  // the plan is chosen here (cams: all of it)
    return openCheckpointStream(spec, steps, stateBytes, stages, parsed ? &*parsed : nullptr,
                                intervals ? RestartData::kInterval : RestartData::kState);
  });
  m.def("storage_strategy_names", &storageStrategyNames,
        "Names of the storage strategies (the C++ factory's).");
  m.def(
      "_check_storage_spec", [](const std::string& spec) { return createStorage(spec)->spec(); },
      "Parses a storage spec with the C++ factory; ValueError for a bad one. Returns the normalized spec.");
}
