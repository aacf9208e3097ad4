// Progress reporting for long jobs (training, embedding, decoder training):
// a one-line bar on stderr with rate and ETA, redrawn at most a few times a
// second, plus free-form figures the job supplies ("loss 0.031 BER 2.1%").
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace watergs {

// Remaining time of a loop whose steps cost a + b * load (for training, the
// load is the Gaussian count, which densification grows in steps every 100
// iterations; a is what a step costs whatever the count: pixels, loss,
// optimizer bookkeeping). The shape a : b is fitted to the whole run so far
// (it needs loads that differ; until then a step costs the same at any
// load), the scale to the recent steps (the last `window_seconds`: a machine
// that got busier or freer is seen at once). The load is extrapolated at its
// mean growth per step since it started growing (not the recent growth,
// which is zero between two densification steps and a whole step's jump
// after one) until `grows_until`, then held. With the default load of 1
// this is the recent rate.
class EtaEstimator {
 public:
  explicit EtaEstimator(double window_seconds = 30)
      : window_seconds_(window_seconds) {}
  // `done` steps were complete `seconds` after the start, at `load`.
  void Add(int64_t done, double seconds, double load = 1);
  // Seconds until `total` steps are done; 0 until two samples differ.
  double Remaining(int64_t total, int64_t grows_until = 0) const;
  // `seconds` of work beside the steps (an embedding's check, a training's
  // held-out test), of `kind`, just done, and due `times_to_come` more
  // times before the end. Kept out of the steps' rate (one check in the
  // window would price every step to come at its cost) and added to the
  // remaining time once per time to come, at the mean of the kind's last
  // three. Call it before the next Add.
  void AddSideWork(const std::string& kind, double seconds,
                   int64_t times_to_come);

 private:
  struct Sample {
    int64_t done;
    double seconds, load;
  };
  // Fits seconds per step = a + b * load over the run's intervals (least
  // squares weighted by steps, a and b >= 0): {a, b}, {1, 0} without loads
  // that differ by 10%.
  std::pair<double, double> CostShape() const;
  // The load's mean growth per step since it started growing (0 before).
  double Growth() const;

  double window_seconds_;
  // Samples at least window/64 apart, the oldest just beyond the window.
  std::deque<Sample> samples_;
  // The whole run at least window/8 apart, thinned to half when full.
  std::vector<Sample> history_;
  // The last sample before the load first changed (done < 0: not yet).
  Sample growth_start_{-1, 0, 0};
  // The latest sample (samples_ may hold an older one at its end).
  Sample latest_{0, 0, 0};
  struct SideWork {
    std::deque<double> recent_seconds;
    int64_t times_to_come = 0;
  };
  std::map<std::string, SideWork> side_work_;
  // All side work so far: subtracted from Add's seconds.
  double side_seconds_ = 0;
};

// What a ProgressBar tells its observer (below).
struct ProgressEvent {
  std::string label;
  int64_t done = 0;
  int64_t total = 0;
  // The figures appended to the line ("loss 0.031  41234 Gaussians").
  std::string status;
  // True at Finish.
  bool finished = false;
};

// Called at every Update and at Finish of the ProgressBars of the thread
// that installed it, before the redraw throttling: lets a program embedding
// the library (the Python module) show progress its own way and stop a job
// by throwing from it, which unwinds the job as an error would. Bars are
// only updated outside parallel regions, so the throw is safe.
using ProgressObserver = std::function<void(const ProgressEvent&)>;
// Installs `observer` for the calling thread (an empty one removes it);
// returns the one it replaces.
ProgressObserver SetProgressObserver(ProgressObserver observer);

class ProgressBar {
 public:
  // `total` steps of work named `label`; `start` is the first step (resume).
  ProgressBar(std::string label, int64_t total, int64_t start = 0);
  // Marks step `done` complete; `status` is appended to the line.
  void Update(int64_t done, const std::string& status = "");
  // The work of a step is proportional to `load` (the Gaussian count),
  // which grows until step `grows_until`: the ETA extrapolates it
  // (EtaEstimator). Set before each Update; the default load is 1.
  void SetLoad(double load, int64_t grows_until);
  // Work beside the steps, timed by the job (EtaEstimator::AddSideWork).
  void AddSideWork(const std::string& kind, double seconds,
                   int64_t times_to_come) {
    eta_.AddSideWork(kind, seconds, times_to_come);
  }
  // Prints `line` on stdout on a line of its own (a result worth keeping,
  // not progress): on a terminal the bar is cleared first and redrawn at the
  // next Update.
  void Print(const std::string& line);
  // Prints the final line with the total time.
  void Finish(const std::string& status = "");
  // Seconds since construction.
  double ElapsedSeconds() const;

 private:
  void Draw(int64_t done, const std::string& status, bool final_line);

  std::string label_;
  int64_t total_;
  int64_t start_;
  std::chrono::steady_clock::time_point begin_;
  std::chrono::steady_clock::time_point last_draw_;
  // True when stderr is a terminal: redraw in place instead of new lines.
  bool interactive_;
  EtaEstimator eta_;
  double load_ = 1;
  int64_t grows_until_ = 0;
};

// Exponential moving average of a figure shown on a progress line (a loss,
// a bit error rate); the first value starts it.
class RunningAverage {
 public:
  // `keep` in [0, 1): the weight of the previous average at each Add.
  explicit RunningAverage(double keep) : keep_(keep) {}
  // Folds in x; returns the new average.
  double Add(double x) {
    value_ = started_ ? keep_ * value_ + (1 - keep_) * x : x;
    started_ = true;
    return value_;
  }
  double value() const { return value_; }

 private:
  double keep_, value_ = 0;
  bool started_ = false;
};

// "1h02m", "3m05s", "12.3s".
std::string FormatDuration(double seconds);

}  // namespace watergs
