// Fuzzing the storage spec strings (engine/storage_spec.h, storage/storage_factory.h): a spec comes
// from the command line or a configuration file, so createStorage must either build a strategy or
// throw std::invalid_argument, whatever the text. A strategy it builds describes itself with spec(),
// and that description must build the same strategy again (the CLI prints it and results files store
// it, so a spec that does not read back would make a run unrepeatable). And a strategy it builds must
// either compute a gradient -- bitwise the full storage's for an exact strategy, with an error
// estimate for an approximate one -- or fail with std::invalid_argument or StorageError: never a
// silent wrong gradient (RunsGiveTheFullGradientOrAnError).
#include "fuzz/fuzz_support.h"

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/storage_factory.h>

#include <filesystem>

namespace hindsight {
namespace {

std::vector<std::string> dictionary() {
  std::vector<std::string> words = {":",
                                    ",",
                                    "=",
                                    "==",
                                    ",,",
                                    "budget=",
                                    "checkpoints=",
                                    "every=",
                                    "dir=",
                                    "level=",
                                    "chunk=",
                                    "keep=",
                                    "codec=",
                                    "tolerance=",
                                    "block=",
                                    "ram=",
                                    "disk=",
                                    "costs=",
                                    "schedule=",
                                    "online=",
                                    "stages=",
                                    "1:1:0:0",
                                    "optimal",
                                    "stride",
                                    "0",
                                    "-1",
                                    "1e400",
                                    "nan",
                                    "inf",
                                    "0x10",
                                    "1e-320",
                                    "9223372036854775807",
                                    "9223372036854775808",
                                    "18446744073709551616",
                                    "0.5",
                                    "KiB",
                                    "MiB",
                                    "GiB",
                                    "TiB",
                                    "kB",
                                    "MB",
                                    "GB",
                                    "B",
                                    "true",
                                    "false",
                                    "zfp",
                                    "round",
                                    " ",
                                    "\t"};
  for (const auto& name : storageStrategyNames()) words.push_back(name);
  return words;
}

// Passes when `spec` builds a strategy whose own spec() builds an equal one, or throws
// std::invalid_argument.
void expectStorageOrInvalidArgument(const std::string& spec) {
  std::unique_ptr<TrajectoryStorage> storage;
  try {
    storage = createStorage(spec);
  } catch (const std::invalid_argument& e) {
    EXPECT_GT(std::string(e.what()).size(), 0u);
    return;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "createStorage threw " << typeid(e).name() << " (" << e.what()
                  << ") instead of std::invalid_argument for '" << fuzz::printable(spec) << "'";
    return;
  }
  ASSERT_NE(storage, nullptr) << spec;
  const std::string canonical = storage->spec();
  try {
    EXPECT_EQ(createStorage(canonical)->spec(), canonical) << "from '" << fuzz::printable(spec) << "'";
  } catch (const std::exception& e) {
    ADD_FAILURE() << "'" << fuzz::printable(spec) << "' built a strategy whose spec '" << canonical
                  << "' does not build again: " << e.what();
  }
}

TEST(StorageSpecFuzz, SeedsBuildStrategies) {
  const auto seeds = fuzz::seedLines("storage_specs.txt");
  ASSERT_GE(seeds.size(), storageStrategyNames().size());
  for (const auto& spec : seeds) {
    EXPECT_NO_THROW(createStorage(spec)) << spec;
    expectStorageOrInvalidArgument(spec);
  }
}

TEST(StorageSpecFuzz, MutatedSpecs) {
  const auto seeds = fuzz::seedLines("storage_specs.txt");
  const auto words = dictionary();
  fuzz::Mutator mutator(fuzz::seed(11));
  for (int k = 0; k < fuzz::cases(6000); ++k) {
    expectStorageOrInvalidArgument(mutator.mutate(mutator.pick(seeds), words, 5));
    if (HasFailure()) return;  // the first failing input is the useful one
  }
}

// Specs put together from the vocabulary alone: a name, then key=value pairs of any key and value.
TEST(StorageSpecFuzz, RandomSpecs) {
  const auto names = storageStrategyNames();
  const std::vector<std::string> keys = {"budget", "checkpoints", "every", "dir", "level", "chunk", "keep",
                                         "codec",  "tolerance",   "block", "ram", "disk",  "",      "x"};
  const std::vector<std::string> values = {
      "0",     "1",    "2",      "-1",       "22",    "23",     "1073741824", "1073741825", "0.5",
      "0.49",  "0.51", "1e-300", "4.9e-324", "1e308", "1e400",  "nan",        "inf",        "-inf",
      "1.5",   "4096", "4KiB",   "0.0001B",  "9e18",  "9.1e18", "8EiB",       "1 MiB",      "true",
      "false", "zfp",  "round",  "/tmp",     "",      "=",      "a=b"};
  fuzz::Mutator mutator(fuzz::seed(12));
  for (int k = 0; k < fuzz::cases(6000); ++k) {
    std::string spec = mutator.pick(names);
    const std::size_t pairs = mutator.below(4);
    for (std::size_t p = 0; p < pairs; ++p) {
      spec += (p == 0 ? ":" : ",") + mutator.pick(keys) + "=" + mutator.pick(values);
    }
    expectStorageOrInvalidArgument(spec);
    if (HasFailure()) return;
  }
}

// StorageSpec's typed getters on their own, with any value text: a value or std::invalid_argument.
TEST(StorageSpecFuzz, TypedGettersOnMutatedValues) {
  const auto words = dictionary();
  fuzz::Mutator mutator(fuzz::seed(13));
  for (int k = 0; k < fuzz::cases(4000); ++k) {
    const std::string value = mutator.mutate("1024", words, 4);
    StorageSpec spec;
    try {
      spec = StorageSpec::parse("s:v=" + value);
    } catch (const std::invalid_argument&) {
      continue;
    }
    try {
      const std::int64_t bytes = spec.bytes("v", 1);
      EXPECT_GT(bytes, 0) << "'" << fuzz::printable(value) << "' accepted as a positive byte count";
    } catch (const std::invalid_argument&) {
    }
    try {
      const std::int64_t n = spec.integer("v", 0, -5, 5);
      EXPECT_TRUE(n >= -5 && n <= 5) << fuzz::printable(value);
    } catch (const std::invalid_argument&) {
    }
    try {
      const double x = spec.real("v", 0.0, 0.0, 1.0);
      EXPECT_TRUE(x >= 0.0 && x <= 1.0) << fuzz::printable(value);
    } catch (const std::invalid_argument&) {
    }
    if (HasFailure()) return;
  }
}

// Every spec that builds, run: the pendulum over 200 rk4 steps (fixed grid, N known) in a scratch
// directory. An exact strategy must give the full storage's bits, an approximate one a finite gradient
// with its error estimate no smaller than its actual error; a failure must be std::invalid_argument
// (a setting outside its validity) or StorageError (a budget or a file).
TEST(StorageSpecFuzz, RunsGiveTheFullGradientOrAnError) {
  const std::string directory =
      (std::filesystem::temp_directory_path() / ("hindsight-fuzz-runs-" + std::to_string(::getpid())))
          .string();
  std::filesystem::create_directories(directory);
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 2.0;
  options.step = 1e-2;
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  const auto seeds = fuzz::seedLines("storage_specs.txt");
  const auto words = dictionary();
  fuzz::Mutator mutator(fuzz::seed(14));
  int ran = 0;
  for (int k = 0; k < fuzz::cases(800); ++k) {
    std::string spec = k < static_cast<int>(seeds.size()) ? seeds[static_cast<std::size_t>(k)]
                                                          : mutator.mutate(mutator.pick(seeds), words, 3);
    // Files only in the scratch directory.
    for (const char* dirKey : {"dir=/tmp/run", "dir=/tmp"}) {
      const std::size_t at = spec.find(dirKey);
      if (at != std::string::npos) spec.replace(at, std::string(dirKey).size(), "dir=" + directory);
    }
    std::unique_ptr<TrajectoryStorage> storage;
    try {
      storage = createStorage(spec);
    } catch (const std::invalid_argument&) {
      continue;
    }
    if ((spec.rfind("disk", 0) == 0 || spec.rfind("multilevel", 0) == 0) &&
        spec.find("dir=") == std::string::npos) {
      continue;  // would write into the system temp directory
    }
    // A mutated directory ("dir=lossy/tmp/r...", relative) would write beside the test, and with keep=true
    // leave its files there.
    bool inside = true;
    for (std::size_t at = spec.find("dir="); at != std::string::npos; at = spec.find("dir=", at + 1)) {
      const std::string value = spec.substr(at + 4, spec.find(',', at) - (at + 4));
      inside = inside && (value == directory || value.rfind(directory + "/", 0) == 0) &&
               value.find("..") == std::string::npos;
    }
    if (!inside) continue;
    try {
      const GradientResult result = computeGradient(problem, p, options, *storage);
      ++ran;
      if (storage->isExact()) {
        EXPECT_EQ(result.objective, reference.objective) << spec;
        EXPECT_TRUE(result.gradient == reference.gradient)
            << "exact strategy '" << fuzz::printable(spec) << "' gave another gradient";
      } else {
        ASSERT_TRUE(result.gradient.allFinite()) << spec;
        const double error = (result.gradient - reference.gradient).norm() / reference.gradient.norm();
        EXPECT_GE(result.summary.gradientErrorEstimate, error)
            << "approximate strategy '" << fuzz::printable(spec) << "' without an estimate of its error "
            << error;
      }
    } catch (const std::invalid_argument&) {
    } catch (const StorageError&) {
    } catch (const std::exception& e) {
      ADD_FAILURE() << "'" << fuzz::printable(spec) << "' failed with " << typeid(e).name() << ": "
                    << e.what();
    }
    if (HasFailure()) break;
  }
  std::filesystem::remove_all(directory);
  EXPECT_GT(ran, 20);
  ::testing::Test::RecordProperty("runs", ran);
}

}  // namespace
}  // namespace hindsight
