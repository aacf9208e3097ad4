// Progress reporting for long jobs (training, embedding, decoder training):
// a one-line bar on stderr with rate and ETA, redrawn at most a few times a
// second, plus free-form figures the job supplies ("loss 0.031 BER 2.1%").
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace watergs {

class ProgressBar {
 public:
  // `total` steps of work named `label`; `start` is the first step (resume).
  ProgressBar(std::string label, int64_t total, int64_t start = 0);
  // Marks step `done` complete; `status` is appended to the line.
  void Update(int64_t done, const std::string& status = "");
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
