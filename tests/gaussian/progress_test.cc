// Tests of the progress-line helpers: the running average shown with a
// loss, the ETA estimate, the duration format of the ETA, and the progress
// observer (what the Python module's callbacks and Ctrl-C go through).
#include "gaussian/util/progress.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

namespace watergs {
namespace {

TEST(RunningAverage, FirstValueStartsItThenOldValuesDecayByKeep) {
  RunningAverage average(0.75);
  EXPECT_EQ(average.Add(8.0), 8.0);
  EXPECT_DOUBLE_EQ(average.Add(0.0), 6.0);  // 0.75 * 8
  EXPECT_DOUBLE_EQ(average.Add(4.0), 5.5);  // 0.75 * 6 + 0.25 * 4
  EXPECT_DOUBLE_EQ(average.value(), 5.5);
}

TEST(RunningAverage, ZeroIsAValueNotAnUnsetMarker) {
  RunningAverage average(0.5);
  average.Add(0.0);
  EXPECT_DOUBLE_EQ(average.Add(2.0), 1.0);
}

// Steps that got slower (more Gaussians): the ETA is at the recent rate,
// not the average since the start.
TEST(EtaEstimator, UsesTheRecentRateNotTheAverageSinceTheStart) {
  EtaEstimator eta(30);
  double t = 0;
  for (int step = 1; step <= 1000; ++step) {
    t += step <= 500 ? 0.01 : 0.1;  // 5 s, then 50 s
    eta.Add(step, t);
  }
  // 1000 steps left at 0.1 s (the average since the start says 55 s).
  EXPECT_NEAR(eta.Remaining(2000), 100.0, 1.0);
  EXPECT_DOUBLE_EQ(eta.Remaining(1000), 0.0);
}

// The case: at step 959 of 2000 the Gaussian count was still
// growing; a step costs in proportion to it.
TEST(EtaEstimator, ExtrapolatesTheLoadUntilItStopsGrowing) {
  const double cost = 1e-5;  // seconds per step and Gaussian
  const auto load = [](int64_t step) { return 1000.0 + 10.0 * step; };
  EtaEstimator eta(30);
  double t = 0;
  for (int64_t step = 1; step <= 959; ++step) {
    t += cost * load(step);
    eta.Add(step, t, load(step));
  }
  // Growing to the end: the exact sum of the remaining steps' costs.
  double growing = 0, stopping = 0;
  for (int64_t step = 960; step <= 2000; ++step) {
    growing += cost * load(step);
    stopping += cost * load(std::min<int64_t>(step, 1500));
  }
  EXPECT_NEAR(eta.Remaining(2000, 15000), growing, 0.02 * growing);
  EXPECT_NEAR(eta.Remaining(2000, 1500), stopping, 0.02 * stopping);
  // The load held at its current value would say far less.
  EXPECT_GT(eta.Remaining(2000, 15000), 1.3 * cost * load(959) * 1041);
}

// A run of `total` steps whose step costs cost(load(step)) seconds, fed to
// an estimator up to step `now`: {its estimate, the true remaining time}.
template <typename Load, typename Cost>
std::pair<double, double> EtaAt(int64_t now, int64_t total, int64_t grows_until,
                                Load load, Cost cost) {
  EtaEstimator eta(30);
  double t = 0, truth = 0;
  for (int64_t step = 1; step <= total; ++step) {
    const double seconds = cost(load(step));
    if (step <= now) {
      t += seconds;
      eta.Add(step, t, load(step));
    } else {
      truth += seconds;
    }
  }
  return {eta.Remaining(total, grows_until), truth};
}

// Training as it is: densification adds Gaussians in one step every 100
// iterations, and a step costs a fixed part (pixels, loss) plus a part per
// Gaussian (the horns run at 252x189: about 0.2 s + 1.1e-5 s per Gaussian on
// busy cores). The ETA must neither jump with each densification step (the
// recent growth is nothing between two steps and a whole step after one:
// an ETA of 40 min, then 8 h, then 47 min, on a 30-minute run) nor price
// the whole step in the Gaussians.
TEST(EtaEstimator, ReadsADensificationStaircaseAsItsMeanGrowth) {
  const auto load = [](int64_t step) {
    return 5000.0 + 7000.0 * std::clamp<int64_t>((step - 500) / 100, 0, 30);
  };
  const auto cost = [](double gaussians) { return 0.2 + 1.1e-5 * gaussians; };
  for (const int64_t now : {999, 1001, 1450, 2001, 2999}) {
    const auto [estimate, truth] = EtaAt(now, 7000, 3500, load, cost);
    EXPECT_NEAR(estimate, truth, 0.15 * truth) << "at step " << now;
  }
  // Just before and just after a step: the same ETA, within 10%.
  const double before = EtaAt(999, 7000, 3500, load, cost).first;
  const double after = EtaAt(1001, 7000, 3500, load, cost).first;
  EXPECT_NEAR(after, before, 0.1 * before);
}

// With a fixed part in every step, pricing the steps by the Gaussians alone
// would put the rest of a run that grows tenfold at nearly ten times the
// present cost per step; the fitted shape keeps the fixed part fixed.
TEST(EtaEstimator, KeepsTheFixedPartOfAStepFixedAsTheLoadGrows) {
  const auto load = [](int64_t step) {
    return 10000.0 + 50.0 * std::min<int64_t>(step, 4000);
  };
  const auto cost = [](double gaussians) { return 0.1 + 1e-6 * gaussians; };
  const auto [estimate, truth] = EtaAt(1000, 7000, 4000, load, cost);
  EXPECT_NEAR(estimate, truth, 0.05 * truth);
  // What a cost in proportion to the load alone would say: the present
  // seconds per Gaussian times the remaining Gaussian-steps.
  double load_sum = 0;
  for (int64_t step = 1001; step <= 7000; ++step) load_sum += load(step);
  const double proportional = cost(load(1000)) / load(1000) * load_sum;
  EXPECT_GT(proportional, 1.5 * truth);
}

// An embedding as it runs: 1,500 steps of 0.9 s with a check every 250
// that renders and decodes the check views (25 s, the length of 28 steps).
// Returns the ETA after step `now`, fed with the checks as side work or,
// when `apart` is false, with their seconds inside the steps' timeline.
double EmbedEtaAt(int64_t now, bool apart) {
  EtaEstimator eta;
  double t = 0;
  for (int64_t step = 1; step <= now; ++step) {
    t += 0.9;
    if (step % 250 == 0) {
      t += 25;
      if (apart) eta.AddSideWork("check", 25, 1500 / 250 - step / 250);
    }
    eta.Add(step, t);
  }
  return eta.Remaining(1500);
}

// The horns embedding's log read "ETA 1h25m" just after its check at
// iteration 1,000 with 7 min to go: a 30-s window holding a check priced
// every step to come at the check's rate. Timed apart, a check is priced
// once per check to come.
TEST(EtaEstimator, PricesChecksApartFromTheSteps) {
  for (const int64_t now : {1000, 1001, 1100, 1249, 1250, 1400}) {
    const int64_t checks_to_come = 1500 / 250 - now / 250;
    const double truth = 0.9 * (1500 - now) + 25.0 * checks_to_come;
    EXPECT_NEAR(EmbedEtaAt(now, true), truth, 0.02 * truth) << "at " << now;
  }
  // Inside the timeline the check makes the ETA jump (the bug).
  const double truth = 0.9 * 500 + 25.0 * 2;
  EXPECT_GT(EmbedEtaAt(1000, false), 2 * truth);
}

TEST(EtaEstimator, PricesSideWorkAtTheMeanOfItsLastThree) {
  EtaEstimator eta;
  eta.Add(0, 0);
  eta.Add(10, 10);  // 1 s a step
  for (const double seconds : {100.0, 2.0, 4.0, 6.0}) {
    eta.AddSideWork("test", seconds, 2);
  }
  eta.AddSideWork("check", 1, 3);
  eta.Add(20, 10 + 112 + 1 + 10);  // the side work is not in the steps' rate
  EXPECT_NEAR(eta.Remaining(30), 10 + 2 * 4.0 + 3 * 1.0, 1e-9);
  eta.AddSideWork("test", 4, 0);  // the last one: nothing more to price
  eta.Add(21, 133 + 4 + 1);
  EXPECT_NEAR(eta.Remaining(30), 9 + 3 * 1.0, 1e-9);
  eta.AddSideWork("test", std::nan(""), 5);  // ignored, as is -1 s
  eta.AddSideWork("test", -1, 5);
  EXPECT_NEAR(eta.Remaining(30), 9 + 3 * 1.0, 1e-9);
}

TEST(FormatDuration, UsesTheLargestUnitThatFits) {
  EXPECT_EQ(FormatDuration(12.3), "12.3s");
  EXPECT_EQ(FormatDuration(185), "3m05s");
  EXPECT_EQ(FormatDuration(3720), "1h02m");
}

// Every Update (not only the redrawn ones) and the Finish reach the
// observer of the thread that installed it, and no other thread's.
TEST(ProgressObserver, SeesEveryStepOfItsThreadsBars) {
  std::vector<ProgressEvent> events;
  const ProgressObserver previous = SetProgressObserver(
      [&events](const ProgressEvent& e) { events.push_back(e); });
  EXPECT_FALSE(previous);
  {
    ProgressBar bar("job", 3);
    bar.Update(1, "a");
    bar.Update(2, "b");
    bar.Update(3, "c");
    bar.Finish("done");
  }
  std::thread other([] {
    ProgressBar bar("other", 1);
    bar.Update(1);
  });
  other.join();
  const ProgressObserver mine = SetProgressObserver(nullptr);
  EXPECT_TRUE(mine);
  ASSERT_EQ(events.size(), 4u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(events[k].label, "job");
    EXPECT_EQ(events[k].done, k + 1);
    EXPECT_EQ(events[k].total, 3);
    EXPECT_EQ(events[k].status, std::string(1, char('a' + k)));
    EXPECT_FALSE(events[k].finished);
  }
  EXPECT_TRUE(events[3].finished);
  EXPECT_EQ(events[3].done, 3);
  EXPECT_EQ(events[3].status, "done");
  // Removed: bars no longer report.
  ProgressBar("job", 1).Update(1);
  EXPECT_EQ(events.size(), 4u);
}

// A throwing observer stops the loop that updates the bar.
TEST(ProgressObserver, ThrowingStopsTheJob) {
  SetProgressObserver([](const ProgressEvent& e) {
    if (e.done == 5) throw std::runtime_error("stop");
  });
  int64_t reached = 0;
  try {
    ProgressBar bar("job", 100);
    for (int64_t step = 1; step <= 100; ++step) {
      reached = step;
      bar.Update(step);
    }
  } catch (const std::runtime_error&) {
  }
  SetProgressObserver(nullptr);
  EXPECT_EQ(reached, 5);
}

}  // namespace
}  // namespace watergs
