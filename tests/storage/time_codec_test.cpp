// The time codec (storage/time_codec.h): lossless blocks restore every bit (smooth series, noise,
// signed zeros, NaN payloads, infinities, subnormals) at every order; blocks decode on their own in any
// order (the backward sweep's reverse order); bounded blocks keep every value within its component's
// bound; any corrupted byte of a block, a wrong block size or a truncated block is a StorageError.
#include <hindsight/storage/time_codec.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace hindsight::internal {
namespace {

// count x n states: smooth components of very different scales, one of noise, one with special values.
std::vector<double> trajectory(std::int64_t first, std::int64_t count, int n, std::mt19937_64& random) {
  std::uniform_real_distribution<double> noise(-1.0, 1.0);
  std::vector<double> rows(static_cast<std::size_t>(count * n));
  for (std::int64_t i = 0; i < count; ++i) {
    const double t = 1e-3 * static_cast<double>(first + i);
    for (int j = 0; j < n; ++j) {
      double x = std::pow(10.0, j % 7 - 3) * std::sin((j + 1) * t + 0.3 * j);
      if (j == n - 1) x = noise(random);
      if (j == n - 2) {
        const double special[] = {0.0,      -0.0,      std::numeric_limits<double>::quiet_NaN(),
                                  HUGE_VAL, -HUGE_VAL, std::numeric_limits<double>::denorm_min(),
                                  1e308,    -1e-310};
        x = (first + i) % 5 == 0 ? special[(first + i) / 5 % 8] : x;
      }
      rows[static_cast<std::size_t>(i * n + j)] = x;
    }
  }
  // A NaN with a payload of its own: the codec must keep the bits, not just "a NaN".
  if (count > 3) {
    const std::uint64_t payload = 0x7ff8dead0000beefULL;
    std::memcpy(&rows[static_cast<std::size_t>(3 * n)], &payload, 8);
  }
  return rows;
}

TEST(TimeCodec, LosslessBlocksRestoreEveryBitAtEveryOrder) {
  const int n = 9;
  std::mt19937_64 random(11);
  for (int order = 0; order <= TimeCodec::kMaxOrder; ++order) {
    for (std::int64_t count : {1, 2, 5, 64, 257}) {
      TimeCodec codec(n, 257);
      const std::vector<double> rows = trajectory(17, count, n, random);
      std::vector<unsigned char> coded(codec.maxEncodedBytes());
      const std::size_t size = codec.encode(rows.data(), count, order, coded.data());
      ASSERT_LE(size, coded.size());
      EXPECT_EQ(TimeCodec::blockStates(coded.data(), size), count);
      std::vector<double> restored(rows.size(), 42.0);
      codec.decode(coded.data(), size, count, restored.data());
      EXPECT_EQ(std::memcmp(restored.data(), rows.data(), rows.size() * 8), 0)
          << "order " << order << ", count " << count;
    }
  }
}

TEST(TimeCodec, PredictionAlongTimeCompressesASmoothSeriesFarBetterThanOrderZero) {
  // One slow sine per component sampled finely: order 6 leaves residuals of a few bits.
  const int n = 4;
  const std::int64_t count = 1024;
  std::vector<double> rows(static_cast<std::size_t>(count * n));
  for (std::int64_t i = 0; i < count; ++i)
    for (int j = 0; j < n; ++j) rows[static_cast<std::size_t>(i * n + j)] = std::sin(1e-3 * i * (j + 1) + j);
  TimeCodec codec(n, count);
  std::vector<unsigned char> coded(codec.maxEncodedBytes());
  const double raw = static_cast<double>(rows.size() * 8);
  const double ratio0 = raw / static_cast<double>(codec.encode(rows.data(), count, 0, coded.data()));
  const double ratio6 = raw / static_cast<double>(codec.encode(rows.data(), count, 6, coded.data()));
  EXPECT_GT(ratio6, 2.0);
  EXPECT_GT(ratio6, 1.5 * ratio0);
}

TEST(TimeCodec, BlocksDecodeOnTheirOwnInReverseAndRandomOrder) {
  const int n = 6;
  const std::int64_t blockStates = 50, blocks = 20;
  std::mt19937_64 random(5);
  TimeCodec codec(n, blockStates);
  std::vector<std::vector<double>> original;
  std::vector<std::vector<unsigned char>> coded;
  for (std::int64_t b = 0; b < blocks; ++b) {
    original.push_back(trajectory(b * blockStates, blockStates, n, random));
    std::vector<unsigned char> block(codec.maxEncodedBytes());
    block.resize(codec.encode(original.back().data(), blockStates, TimeCodec::kLosslessOrder, block.data()));
    coded.push_back(std::move(block));
  }
  std::vector<std::int64_t> order;
  for (std::int64_t b = blocks - 1; b >= 0; --b) order.push_back(b);  // the backward sweep
  std::vector<std::int64_t> shuffled = order;
  std::shuffle(shuffled.begin(), shuffled.end(), random);
  order.insert(order.end(), shuffled.begin(), shuffled.end());
  TimeCodec reader(n, blockStates);  // a codec object that never saw the blocks
  std::vector<double> restored(static_cast<std::size_t>(blockStates * n));
  for (std::int64_t b : order) {
    const auto& block = coded[static_cast<std::size_t>(b)];
    reader.decode(block.data(), block.size(), blockStates, restored.data());
    EXPECT_EQ(std::memcmp(restored.data(), original[static_cast<std::size_t>(b)].data(), restored.size() * 8),
              0)
        << "block " << b;
  }
}

TEST(TimeCodec, BoundedBlocksKeepEveryValueWithinItsComponentsBound) {
  const int n = 9;
  std::mt19937_64 random(3);
  for (int order : {0, 1, 2, 4}) {
    for (double tolerance : {1e-2, 1e-6, 1e-12}) {
      const std::int64_t count = 300;
      const std::vector<double> rows = trajectory(0, count, n, random);
      std::vector<double> bounds(n), scale(n, 0.0);
      for (int j = 0; j < n; ++j) {
        for (std::int64_t i = 0; i < count; ++i) {
          const double x = std::abs(rows[static_cast<std::size_t>(i * n + j)]);
          if (std::isfinite(x))
            scale[static_cast<std::size_t>(j)] = std::max(scale[static_cast<std::size_t>(j)], x);
        }
        bounds[static_cast<std::size_t>(j)] = tolerance * scale[static_cast<std::size_t>(j)];
      }
      TimeCodec codec(n, count);
      std::vector<unsigned char> coded(codec.maxEncodedBytes());
      double worst = -1.0;
      const std::size_t size =
          codec.encodeBounded(rows.data(), count, order, bounds.data(), coded.data(), scale.data(), &worst);
      std::vector<double> restored(rows.size());
      codec.decode(coded.data(), size, count, restored.data());
      double measured = 0.0;
      for (std::int64_t i = 0; i < count; ++i) {
        for (int j = 0; j < n; ++j) {
          const double x = rows[static_cast<std::size_t>(i * n + j)],
                       y = restored[static_cast<std::size_t>(i * n + j)];
          if (!std::isfinite(x)) {
            EXPECT_EQ(std::memcmp(&x, &y, 8), 0) << "non-finite values are kept exactly";
            continue;
          }
          EXPECT_LE(std::abs(y - x), bounds[static_cast<std::size_t>(j)]) << i << ", " << j;
          if (scale[static_cast<std::size_t>(j)] > 0.0)
            measured = std::max(measured, std::abs(y - x) / scale[static_cast<std::size_t>(j)]);
        }
      }
      EXPECT_EQ(worst, measured) << "the reported error is the one made";
      EXPECT_LE(worst, tolerance);
      if (tolerance >= 1e-6)
        EXPECT_GT(worst, 0.0) << "a bounded block at " << tolerance << " loses something";
    }
  }
}

TEST(TimeCodec, EveryCorruptedByteIsAStorageError) {
  const int n = 3;
  const std::int64_t count = 40;
  std::mt19937_64 random(9);
  const std::vector<double> rows = trajectory(0, count, n, random);
  TimeCodec codec(n, count);
  std::vector<unsigned char> coded(codec.maxEncodedBytes());
  const std::vector<double> bounds(n, 1e-6);
  for (bool bounded : {false, true}) {
    coded.resize(codec.maxEncodedBytes());
    const std::size_t size = bounded ? codec.encodeBounded(rows.data(), count, 1, bounds.data(), coded.data())
                                     : codec.encode(rows.data(), count, 6, coded.data());
    coded.resize(size);
    std::vector<double> restored(rows.size());
    for (std::size_t byte = 0; byte < size; ++byte) {
      std::vector<unsigned char> broken = coded;
      broken[byte] ^= 0x24;
      EXPECT_THROW(codec.decode(broken.data(), size, count, restored.data(), "test block"), StorageError)
          << "byte " << byte << " of " << size;
    }
    EXPECT_THROW(codec.decode(coded.data(), size - 1, count, restored.data()), StorageError) << "truncated";
    EXPECT_THROW(codec.decode(coded.data(), size, count - 1, restored.data()), StorageError) << "wrong count";
    try {
      std::vector<unsigned char> broken = coded;
      broken[size - 3] ^= 1;
      codec.decode(broken.data(), size, count, restored.data(), "block 7 of the trajectory");
      ADD_FAILURE() << "no error";
    } catch (const StorageError& e) {
      EXPECT_NE(std::string(e.what()).find("block 7 of the trajectory is corrupted: checksum mismatch"),
                std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace hindsight::internal
