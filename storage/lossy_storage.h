// Strategy "lossy": every step's state in memory, compressed with a bounded error (docs/design.md §6).
// Not exact (isExact() is false): the backward sweep sees states within the tolerance of the recorded
// ones, so the gradient is that of a perturbed trajectory; its error is O(tolerance) (measured in
// tests/storage/lossy_storage_test.cpp). Nothing is recomputed.
//
// Spec: lossy:target=T[,sensitivity=S][,budget=BYTES][,block=STATES]
//       lossy:codec=zfp|round|time,tolerance=T[,budget=BYTES][,block=STATES]   (for experts)
//   target=T     the relative 2-norm error ||g - g_full|| / ||g_full|| of the gradient the user
//                accepts, T in [1e-14, 0.1]. Codec time with tolerance T / kGradientSensitivity (= 10): the
//                bound of each component is that fraction of its largest magnitude in the block. The
//                run summary reports gradient_error_estimate = kGradientSensitivity x the largest
//                relative state error actually made (<= T). kGradientSensitivity is calibrated, not
//                derived: the measured ratio of gradient error to relative state error was at most
//                0.09 on the reduced rod (200x12, T = 3 and 10 s), 4.6 on the full-order rod (100
//                trbdf2 steps; the reason for 10 rather than 1), 0.6 on the synthetic slider-crank of
//                tests/problems/rod, 0.22 on the pendulum and 0.006 on the reaction-diffusion problem;
//                the tests check achieved <= T on these (docs/theory/storage.md, "Compression along time").
//                It is a documented estimate, not a proof: a problem whose gradient is more sensitive to its
//                states than these can exceed T, and components that fall by decades within a block
//                (Robertson) lose their small values' digits.
//   sensitivity  with target: the factor S of the problem at hand in place of kGradientSensitivity, in
//                [1e-3, 1e3]: codec time with tolerance T / S, gradient_error_estimate = S x the relative
//                state error made. A calibration that belongs to a problem and its integrator, measured
//                against full storage (calibrate() lets an application set its own measured one; a
//                sensitivity= in the spec wins). The piston rod's reduced model sets S = 0.3 for
//                generalized-alpha and rk4 (measured ratio at most 0.05 and 0.09; docs/theory/storage.md,
//                "Compression along time").
//   codec=time   prediction along time with quantized residuals (storage/time_codec.h): every
//                restored value is within tolerance x max|component| over its block of the recorded
//                one, tolerance in (0, 0.5].
//   codec=zfp    ZFP fixed-accuracy mode on 1-D arrays of doubles; every restored value is within
//                the ABSOLUTE tolerance T of the recorded one (Lindstrom 2014). gradient_error_estimate =
//                kGradientSensitivity x the largest T / max|component| over the blocks (infinite when a
//                component is zero over a block).
//   codec=round  mantissa rounding to the fewest bits m with 2^-(m+1) <= T (round to nearest, ties to
//                even), then byte shuffle and zstd; every restored value x~ has |x~ - x| <= T |x|, a
//                RELATIVE bound, T in (0, 0.5] (Kloewer, Razinger, Dominguez, Duben & Palmer 2021);
//                gradient_error_estimate = kGradientSensitivity x T.
//   budget       bytes held in memory (default 4 GiB): the compressed blocks plus three work buffers
//                of one block each (raw states, transposed/shuffled states, compressor output).
//   block        states compressed together (default: about 256 KiB of states, at most 4096; at
//                least 16 for the time codec).
// States are compressed in blocks. When a block has at least as many states as a state has
// components, it is stored component-major (each component's values over the block's steps are
// contiguous), so smoothness in time helps the codecs even for tiny states; otherwise (large
// states, few per block) state by state, so smoothness in space does. The achieved
// ratio is in counters() (uncompressedBytes / compressedBytes). A compressed block is freed as soon
// as the backward sweep has decoded it.
//
// Thread-safety: one object, one thread. Throws StorageError when the budget would be exceeded or a
// codec fails, std::invalid_argument for bad options.
//
// References: P. Lindstrom, "Fixed-Rate Compressed Floating-Point Arrays", IEEE TVCG 20(12), 2014;
// M. Kloewer et al., "Compressing atmospheric data into its real information content", Nature
// Computational Science 1, 713-724, 2021; Kukreja et al. 2022 (lossy checkpoint compression for
// adjoints).
#pragma once

#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>
#include <hindsight/storage/time_codec.h>

#include <memory>
#include <string>
#include <vector>

namespace hindsight {

class LossyStorage final : public TrajectoryStorage {
 public:
  enum class Codec { kZfp, kRound, kTime };
  /// Relative gradient error per relative state error assumed by target=T (calibrated, see above).
  static constexpr double kGradientSensitivity = 10.0;
  static constexpr double kMinTarget = 1e-14;
  static constexpr double kMaxTarget = 0.1;
  static constexpr double kMinSensitivity = 1e-3;
  static constexpr double kMaxSensitivity = 1e3;
  static constexpr std::int64_t kDefaultBudget = std::int64_t{4} << 30;

  struct Options {
    Codec codec = Codec::kZfp;
    double tolerance =
        1e-8;             ///< absolute for zfp, relative for round, relative to the block's scale for time
    double target = 0.0;  ///< > 0: the gradient error target (codec time, tolerance from it)
    /// With target: the calibrated ratio of relative gradient error to relative state error; 0: none given
    /// (kGradientSensitivity, or what calibrate() sets).
    double sensitivity = 0.0;
    std::int64_t budgetBytes = kDefaultBudget;
    std::int64_t blockStates = 0;  ///< 0: automatic
    /// The strategy "packed": codec time without a bound, every bit restored (isExact() is true).
    bool lossless = false;
    bool IsValid(std::string* error) const;
  };

  /// Throws std::invalid_argument when !options.IsValid().
  explicit LossyStorage(Options options);
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  /// "packed[:budget=B,block=S]": every state in memory, coded losslessly along time (the same blocks,
  /// codec and integrity checks as lossy:codec=time and disk's default codec, without quantization).
  static std::unique_ptr<TrajectoryStorage> createPacked(const StorageSpec& spec);

  std::string spec() const override;
  bool isExact() const override { return options_.lossless; }

  /// The factor target=T plans by and the estimate reports: the spec's sensitivity=, else the last
  /// calibrate(), else kGradientSensitivity.
  double sensitivity() const;
  /// An application's measured sensitivity for its problem and integrator (in [kMinSensitivity,
  /// kMaxSensitivity]), used by target=T when the spec gives none; no effect without target. Takes effect
  /// at the next begin().
  void calibrate(double sensitivity);

  /// Mantissa bits kept by codec=round for a relative tolerance (0..52).
  static int keptMantissaBits(double relativeTolerance);
  /// Rounds each finite value to `bits` mantissa bits, to nearest, ties to even.
  static void roundMantissas(double* values, std::size_t count, int bits);

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;
  void compressBlock();
  void decodeBlock(std::size_t index);

  struct Block {
    std::int64_t states;
    std::int64_t bytes;
    std::unique_ptr<unsigned char[]> data;
  };

  Options options_;
  double calibrated_ = 0.0;  // calibrate()'s sensitivity; 0: none
  std::int64_t blockStates_ = 1;
  bool componentMajor_ = true;
  std::vector<double> raw_;   // state-major: the block being filled / zstd scratch
  std::vector<double> work_;  // component-major: the block being compressed or decoded
  std::vector<unsigned char> scratch_;
  std::unique_ptr<internal::TimeCodec> timeCodec_;
  std::vector<double> bounds_, scale_;
  double worstRelativeError_ = 0.0;
  std::int64_t statesInRaw_ = 0;
  std::vector<Block> blocks_;
  std::int64_t decodedBlock_ = -1;
  std::int64_t decodedStates_ = 0;
};

}  // namespace hindsight
