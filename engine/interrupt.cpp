#include <hindsight/engine/interrupt.h>

#include <atomic>

namespace hindsight {
namespace {
std::atomic<InterruptPoll> installed{nullptr};
}  // namespace

InterruptPoll setInterruptPoll(InterruptPoll poll) { return installed.exchange(poll); }

void pollInterrupt() {
  const InterruptPoll poll = installed.load(std::memory_order_relaxed);
  if (poll != nullptr) poll();
}

}  // namespace hindsight
