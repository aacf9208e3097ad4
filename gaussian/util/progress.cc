#include "gaussian/util/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

namespace watergs {
namespace {

thread_local ProgressObserver progress_observer;

void Notify(const std::string& label, int64_t done, int64_t total,
            const std::string& status, bool finished) {
  if (progress_observer) {
    progress_observer(ProgressEvent{label, done, total, status, finished});
  }
}

// Weighted least-squares line y = intercept + slope * x.
struct LineFit {
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  void Add(double x, double y, double w = 1) {
    sw += w;
    sx += w * x;
    sy += w * y;
    sxx += w * x * x;
    sxy += w * x * y;
  }
  // {intercept, slope}; false without two distinct x.
  bool Solve(double* intercept, double* slope) const {
    if (!(sw > 0)) return false;
    const double mx = sx / sw, my = sy / sw, var = sxx / sw - mx * mx;
    if (!(var > 0)) return false;
    *slope = (sxy / sw - mx * my) / var;
    *intercept = my - *slope * mx;
    return true;
  }
};

}  // namespace

ProgressObserver SetProgressObserver(ProgressObserver observer) {
  std::swap(observer, progress_observer);
  return observer;
}

void EtaEstimator::Add(int64_t done, double seconds, double load) {
  seconds -= side_seconds_;
  if (growth_start_.done < 0 && (samples_.size() || history_.size()) &&
      load != latest_.load) {
    growth_start_ = latest_;
  }
  latest_ = {done, seconds, load};
  if (samples_.empty() ||
      seconds - samples_.back().seconds >= window_seconds_ / 64) {
    samples_.push_back(latest_);
  }
  // Keep one sample at or beyond the window's start.
  while (samples_.size() > 2 &&
         seconds - samples_[1].seconds >= window_seconds_) {
    samples_.pop_front();
  }
  constexpr size_t kMaxHistory = 512;
  if (history_.empty() ||
      seconds - history_.back().seconds >= window_seconds_ / 8) {
    if (history_.size() == kMaxHistory) {
      for (size_t i = 1; 2 * i < history_.size(); ++i) {
        history_[i] = history_[2 * i];
      }
      history_.resize(kMaxHistory / 2);
    }
    history_.push_back(latest_);
  }
}

std::pair<double, double> EtaEstimator::CostShape() const {
  // Seconds per step against each interval's mean load, weighted by steps.
  LineFit fit;
  double low = INFINITY, high = 0;
  for (size_t i = 1; i < history_.size(); ++i) {
    const Sample& p = history_[i - 1];
    const Sample& q = history_[i];
    const double steps = double(q.done - p.done);
    if (!(steps > 0) || !(q.seconds > p.seconds)) continue;
    const double x = 0.5 * (p.load + q.load);
    fit.Add(x, (q.seconds - p.seconds) / steps, steps);
    low = std::min(low, x);
    high = std::max(high, x);
  }
  double a = 0, b = 0;
  if (!(high > 1.1 * low) || !fit.Solve(&a, &b)) return {1, 0};
  if (!(b > 0)) return {1, 0};  // no cost in the load: a constant
  if (!(a > 0)) return {0, 1};  // all of it in the load
  return {a, b};
}

double EtaEstimator::Growth() const {
  if (growth_start_.done < 0) return 0;
  // Least-squares slope of the load against the steps since it started
  // growing: a staircase of densification steps reads as its mean slope
  // whether the latest sample sits just before a step or just after it.
  LineFit fit;
  fit.Add(double(growth_start_.done), growth_start_.load);
  for (const Sample& p : history_) {
    if (p.done > growth_start_.done && p.done < latest_.done) {
      fit.Add(double(p.done), p.load);
    }
  }
  fit.Add(double(latest_.done), latest_.load);
  double intercept = 0, slope = 0;
  if (!fit.Solve(&intercept, &slope)) return 0;
  return std::max(0.0, slope);
}

void EtaEstimator::AddSideWork(const std::string& kind, double seconds,
                               int64_t times_to_come) {
  if (!(seconds >= 0) || !std::isfinite(seconds)) return;
  side_seconds_ += seconds;
  SideWork& work = side_work_[kind];
  work.recent_seconds.push_back(seconds);
  if (work.recent_seconds.size() > 3) work.recent_seconds.pop_front();
  work.times_to_come = std::max<int64_t>(0, times_to_come);
}

double EtaEstimator::Remaining(int64_t total, int64_t grows_until) const {
  if (samples_.empty()) return 0;
  const Sample& first = samples_.front();
  const int64_t steps = latest_.done - first.done;
  const double seconds = latest_.seconds - first.seconds;
  if (steps <= 0 || !(seconds > 0)) return 0;
  const auto [a, b] = CostShape();
  // The recent steps' seconds per unit of modelled cost (a + b * load at
  // the window's mean load).
  const double mean_load = 0.5 * (first.load + latest_.load);
  const double unit = std::max(a + b * mean_load, 1e-12);
  const double scale = seconds / (double(steps) * unit);
  const double growth = Growth();
  // Steps left while the load grows (g), then at its final value (h).
  const double left = double(std::max<int64_t>(0, total - latest_.done));
  const double g = std::clamp(double(grows_until - latest_.done), 0.0, left);
  const double h = left - g;
  const double load_sum =
      latest_.load * left + growth * g * (g + 1) / 2 + growth * g * h;
  double side = 0;
  for (const auto& [kind, work] : side_work_) {
    double sum = 0;
    for (double s : work.recent_seconds) sum += s;
    side += work.times_to_come * sum / work.recent_seconds.size();
  }
  return scale * (a * left + b * load_sum) + side;
}

ProgressBar::ProgressBar(std::string label, int64_t total, int64_t start)
    : label_(std::move(label)),
      total_(total),
      start_(start),
      begin_(std::chrono::steady_clock::now()),
      last_draw_(begin_ - std::chrono::seconds(10)),
      interactive_(::isatty(STDERR_FILENO)) {}

double ProgressBar::ElapsedSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() -
                                       begin_)
      .count();
}

void ProgressBar::SetLoad(double load, int64_t grows_until) {
  load_ = load;
  grows_until_ = grows_until;
}

void ProgressBar::Print(const std::string& line) {
  if (interactive_) {
    std::cerr << "\r\033[K";
    std::cerr.flush();
  }
  std::cout << line << "\n";
  std::cout.flush();
  last_draw_ = {};  // redraw at the next Update
}

void ProgressBar::Update(int64_t done, const std::string& status) {
  Notify(label_, done, total_, status, false);
  const auto now = std::chrono::steady_clock::now();
  eta_.Add(done, ElapsedSeconds(), load_);
  // Terminals get 5 redraws a second; logs one line every 10 seconds.
  const auto period = interactive_ ? std::chrono::milliseconds(200)
                                   : std::chrono::milliseconds(10000);
  if (now - last_draw_ < period && done < total_) return;
  last_draw_ = now;
  Draw(done, status, false);
}

void ProgressBar::Finish(const std::string& status) {
  Notify(label_, total_, total_, status, true);
  Draw(total_, status, true);
}

void ProgressBar::Draw(int64_t done, const std::string& status,
                       bool final_line) {
  const double elapsed = ElapsedSeconds();
  const double rate = elapsed > 0 ? (done - start_) / elapsed : 0.0;
  double eta = eta_.Remaining(total_, grows_until_);
  // Before two samples: the rate since the start.
  if (!(eta > 0) && rate > 0) eta = (total_ - done) / rate;
  const int width = 24;
  const int filled =
      total_ > 0 ? static_cast<int>(width * double(done) / total_) : width;
  std::ostringstream line;
  line << label_ << " [";
  for (int i = 0; i < width; ++i) line << (i < filled ? '#' : '.');
  line << "] " << done << "/" << total_;
  char buf[64];
  std::snprintf(buf, sizeof(buf), " %.1f/s", rate);
  line << buf;
  line << (final_line ? " in " + FormatDuration(elapsed)
                      : " ETA " + FormatDuration(eta));
  if (!status.empty()) line << "  " << status;
  if (interactive_) {
    std::cerr << "\r" << line.str() << "\033[K" << (final_line ? "\n" : "");
  } else {
    std::cerr << line.str() << "\n";
  }
  std::cerr.flush();
}

std::string FormatDuration(double seconds) {
  char buf[32];
  if (seconds < 60) {
    std::snprintf(buf, sizeof(buf), "%.1fs", seconds);
  } else if (seconds < 3600) {
    std::snprintf(buf, sizeof(buf), "%dm%02ds", int(seconds) / 60,
                  int(seconds) % 60);
  } else {
    std::snprintf(buf, sizeof(buf), "%dh%02dm", int(seconds) / 3600,
                  (int(seconds) % 3600) / 60);
  }
  return buf;
}

}  // namespace watergs
