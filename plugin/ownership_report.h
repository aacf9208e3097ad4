// The ownership report: the evidence an owner hands over to someone who will
// not read JSON, as one self-contained HTML page (images embedded as PNG data
// URIs, the per-view BER chart as inline SVG, no script and no network).
// Plain data in, HTML out: `watergs report`, `embed --report` and
// `eval --report` fill the data (report_evidence.h) and share the page.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gaussian/image.h"
#include "watermark/evaluation.h"
#include "watermark/extractor.h"

namespace watergs {

// A file the evidence rests on, identified by size and checksum.
struct ReportFile {
  // What it is ("decoder", "raw model", "watermarked model", "suspect copy").
  std::string role;
  // As the user named it.
  std::string path;
  uint64_t bytes = 0;
  // FNV-1a 64 of the whole file (what make_decoder prints for a decoder).
  uint64_t fnv1a = 0;
};

// One view shown in full: both renders and what separates them.
struct ReportView {
  std::string name;
  // Renders in [0, 1] at the size shown (at most kReportImageWidth wide).
  ImageRGB raw, watermarked;
  // |watermarked - raw| x 10, computed at full size, then resized.
  ImageRGB difference;
  // Full render size (the images above may be smaller).
  int render_width = 0, render_height = 0;
  // Watermarked vs raw render at full size.
  double psnr = 0, ssim = 0;
  // Bits the watermarked render alone reads wrong.
  int bit_errors = 0;
};

// A command that reproduces part of the report.
struct ReportCommand {
  // What it reproduces, in words.
  std::string caption;
  // The shell command line.
  std::string command;
};

// Widest image stored in the page: larger renders are downscaled (area
// averaging) so that the file stays small.
inline constexpr int kReportImageWidth = 480;
// The difference image's amplification.
inline constexpr double kReportDifferenceGain = 10;

struct OwnershipReport {
  // "watergs 1.2.3".
  std::string generator;
  // The claimed message as the owner typed it ("text:WGS-26").
  std::string message_text;
  // SHA-256 of the owner's key (KeyFingerprint); empty: unkeyed claim.
  std::string key_fingerprint;
  // The decoder and the models (raw, watermarked, suspect copies).
  ReportFile decoder;
  std::vector<ReportFile> files;
  // The watermarked model the claim is about, as the user named it.
  std::string watermarked_path;
  // The workspace whose cameras were rendered, and how many views it has.
  std::string workspace_path;
  size_t workspace_views = 0;
  // Quality and robustness on the evaluated views; suspect copies are
  // robustness rows of model "file" (after the raw model's row).
  EvaluationReport evaluation;
  // The watermarked model read without attack: the claim, in the reading
  // the report was asked for (owner_reading: minus the raw model's logits,
  // extractor.h), and the same renders in the other reading.
  bool owner_reading = true;
  ExtractionResult claim;
  ExtractionResult claim_other;
  // The raw model read the same way (the contrast an owner shows).
  ExtractionResult raw;
  // Views shown in full.
  std::vector<ReportView> shown;
  // Reproduces each robustness row (parallel to evaluation.robustness).
  std::vector<std::string> row_commands;
  // Reproduce the whole report and the claim.
  std::vector<ReportCommand> commands;
};

// Escapes &, <, >, " and ' for HTML text and attribute values.
std::string HtmlEscape(const std::string& text);

// Standard base64 (RFC 4648, with padding).
std::string Base64(const std::string& bytes);

// 8-bit PNG of an image in [0, 1] (values clamped).
std::string EncodePng(const ImageRGB& image);

// The page. Every string from the user (paths, message, view names) is
// escaped; the data behind it is also embedded as JSON (a
// <script type="application/json" id="watergs-report-data"> block, which
// browsers do not run) for programs that check a report.
std::string OwnershipReportToHtml(const OwnershipReport& report);

}  // namespace watergs
