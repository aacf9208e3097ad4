#include "gaussian/progress.h"

#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <sstream>

namespace watergs {

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

void ProgressBar::Update(int64_t done, const std::string& status) {
  const auto now = std::chrono::steady_clock::now();
  // Terminals get 5 redraws a second; logs one line every 10 seconds.
  const auto period = interactive_ ? std::chrono::milliseconds(200)
                                   : std::chrono::milliseconds(10000);
  if (now - last_draw_ < period && done < total_) return;
  last_draw_ = now;
  Draw(done, status, false);
}

void ProgressBar::Finish(const std::string& status) {
  Draw(total_, status, true);
}

void ProgressBar::Draw(int64_t done, const std::string& status,
                       bool final_line) {
  const double elapsed = ElapsedSeconds();
  const double rate = elapsed > 0 ? (done - start_) / elapsed : 0.0;
  const double eta = rate > 0 ? (total_ - done) / rate : 0.0;
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
