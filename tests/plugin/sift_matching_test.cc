// Exact SIFT matching (MatchSiftDescriptors) against a plain double-loop twin
// of COLMAP's rules, COLMAP's pair lists, and reading descriptors from a
// COLMAP database.
#include "plugin/sift_matching.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <tuple>

#include "gaussian/util/error.h"
#include "plugin/colmap_database.h"

namespace watergs {
namespace {

// Why the reference twin turned a first-image descriptor down (or kept it).
enum Outcome { kMatched, kNoNeighbour, kTooFar, kAmbiguous, kNotMutual };

// COLMAP's one-way rule in double over integer dot products: the neighbour
// of row `i` of `from` in `to`, or -1 with the reason in `why`.
int OneWay(const SiftDescriptors& from, int i, const SiftDescriptors& to,
           const SiftMatchOptions& o, Outcome* why) {
  int64_t best = 0, second = 0;
  int at = -1;
  for (int j = 0; j < to.rows(); ++j) {
    int64_t dot = 0;
    for (int d = 0; d < 128; ++d) dot += int64_t(from(i, d)) * to(j, d);
    if (dot > best) {
      second = best, best = dot, at = j;
    } else if (dot > second) {
      second = dot;
    }
  }
  const double angle = std::acos(std::min(best / 262144.0, 1.0));
  const double second_angle = std::acos(std::min(second / 262144.0, 1.0));
  *why = at < 0                                  ? kNoNeighbour
         : angle > o.max_distance                ? kTooFar
         : !(angle < o.max_ratio * second_angle) ? kAmbiguous
                                                 : kMatched;
  return *why == kMatched ? at : -1;
}

FeatureMatches ReferenceMatches(const SiftDescriptors& a,
                                const SiftDescriptors& b,
                                const SiftMatchOptions& o,
                                std::map<Outcome, int>* outcomes) {
  FeatureMatches matches;
  for (int i = 0; i < a.rows(); ++i) {
    Outcome why, back_why;
    const int j = OneWay(a, i, b, o, &why);
    if (j >= 0 && o.cross_check && OneWay(b, j, a, o, &back_why) != i) {
      why = kNotMutual;
    }
    ++(*outcomes)[why];
    if (why == kMatched) matches.emplace_back(i, j);
  }
  return matches;
}

// SIFT-like rows: non-negative, length about 512, clipped to a byte.
SiftDescriptors RandomDescriptors(int rows, std::mt19937* rng) {
  std::gamma_distribution<double> spiky(0.3, 1.0);
  SiftDescriptors d(rows, 128);
  for (int r = 0; r < rows; ++r) {
    Eigen::Matrix<double, 128, 1> v;
    for (int k = 0; k < 128; ++k) v[k] = spiky(*rng);
    v *= 512.0 / v.norm();
    for (int k = 0; k < 128; ++k) {
      d(r, k) = uint8_t(std::min(255.0, std::round(v[k])));
    }
  }
  return d;
}

// `b`: `a`'s rows shuffled, each moved by noise of `noise` (0 to 1 of its
// length), some rows twice (ambiguous), plus unrelated rows.
SiftDescriptors Perturbed(const SiftDescriptors& a, double noise,
                          std::mt19937* rng) {
  const SiftDescriptors fresh = RandomDescriptors(a.rows(), rng);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Eigen::Matrix<uint8_t, 1, 128>> rows;
  for (int r = 0; r < a.rows(); ++r) {
    const double t = noise * u(*rng);
    Eigen::Matrix<uint8_t, 1, 128> row;
    for (int k = 0; k < 128; ++k) {
      row[k] = uint8_t(std::round((1 - t) * a(r, k) + t * fresh(r, k)));
    }
    rows.push_back(row);
    if (r % 7 == 0) rows.push_back(row);  // a twin: the ratio test's case
    if (r % 5 == 0) rows.push_back(fresh.row(r));
  }
  std::shuffle(rows.begin(), rows.end(), *rng);
  SiftDescriptors b(rows.size(), 128);
  for (size_t r = 0; r < rows.size(); ++r) b.row(r) = rows[r];
  return b;
}

TEST(SiftMatching, EqualsTheReferenceOnEveryRuleCOLMAPApplies) {
  std::mt19937 rng(7);
  for (const double noise : {0.2, 0.6, 1.0}) {
    const SiftDescriptors original = RandomDescriptors(300, &rng);
    const SiftDescriptors b = Perturbed(original, noise, &rng);
    // `a` also holds noisy copies of some rows (each may find its original's
    // match in `b`, which prefers the original: the cross-check's case),
    // shuffled, so that a row of `b` meets its best after its second best.
    const SiftDescriptors copies = Perturbed(original.topRows(60), 0.3, &rng);
    SiftDescriptors a(original.rows() + copies.rows(), 128);
    a << original, copies;
    std::vector<int> order(a.rows());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    a = SiftDescriptors(a(order, Eigen::all));
    for (const bool cross_check : {true, false}) {
      SiftMatchOptions options;
      options.cross_check = cross_check;
      std::map<Outcome, int> outcomes;
      const FeatureMatches expected =
          ReferenceMatches(a, b, options, &outcomes);
      EXPECT_EQ(MatchSiftDescriptors(a, b, options), expected)
          << "noise " << noise << " cross-check " << cross_check;
      if (noise == 0.6 && cross_check) {
        // Each rule decides some rows here, so each is compared above.
        for (const Outcome o : {kMatched, kTooFar, kAmbiguous, kNotMutual}) {
          EXPECT_GT(outcomes[o], 0) << "no row decided by rule " << o;
        }
      }
    }
  }
}

TEST(SiftMatching, NoFeaturesNoMatchesAndIdenticalImagesMatchThemselves) {
  std::mt19937 rng(3);
  const SiftDescriptors a = RandomDescriptors(50, &rng);
  EXPECT_TRUE(MatchSiftDescriptors(a, SiftDescriptors(0, 128)).empty());
  EXPECT_TRUE(MatchSiftDescriptors(SiftDescriptors(0, 128), a).empty());
  // Random rows can lie close enough to fail the ratio test, not more.
  const FeatureMatches self = MatchSiftDescriptors(a, a);
  EXPECT_GE(self.size(), 45u);
  for (const auto& [i, j] : self) EXPECT_EQ(i, j);
}

TEST(SiftMatching, PairListsAreCOLMAPs) {
  EXPECT_EQ(ExhaustivePairs(48).size(), 1128u);
  EXPECT_TRUE(ExhaustivePairs(1).empty());
  // COLMAP 3.8 sequential, overlap 10: offsets 1..9 and 1, 2, 4, ..., 512.
  const std::set<int> offsets = {1, 2,  3,  4,  5,   6,   7,  8,
                                 9, 16, 32, 64, 128, 256, 512};
  for (const int n : {2, 11, 48, 101, 700}) {
    std::set<std::pair<int, int>> expected;
    for (int i = 0; i < n; ++i) {
      for (const int d : offsets) {
        if (i + d < n) expected.insert({i, i + d});
      }
    }
    const auto pairs = SequentialPairs(n, 10, true);
    const std::set<std::pair<int, int>> got(pairs.begin(), pairs.end());
    EXPECT_EQ(got, expected);
    EXPECT_EQ(pairs.size(), expected.size()) << "a pair twice, n " << n;
  }
}

// A database with COLMAP's two tables and the given descriptor rows.
void WriteDatabase(const std::string& path,
                   const std::vector<std::tuple<int, std::string, int, int>>&
                       images_rows_cols) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "CREATE TABLE images (image_id INTEGER PRIMARY KEY, "
                         "name TEXT, camera_id INTEGER);"
                         "CREATE TABLE descriptors (image_id INTEGER PRIMARY "
                         "KEY, rows INTEGER, cols INTEGER, data BLOB);",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  for (const auto& [id, name, rows, cols] : images_rows_cols) {
    sqlite3_stmt* s = nullptr;
    sqlite3_prepare_v2(db, "INSERT INTO images VALUES (?, ?, 1)", -1, &s,
                       nullptr);
    sqlite3_bind_int(s, 1, id);
    sqlite3_bind_text(s, 2, name.c_str(), -1, SQLITE_TRANSIENT);
    ASSERT_EQ(sqlite3_step(s), SQLITE_DONE);
    sqlite3_finalize(s);
    std::vector<uint8_t> data(size_t(rows) * cols);
    for (size_t k = 0; k < data.size(); ++k) data[k] = uint8_t(id * 31 + k);
    sqlite3_prepare_v2(db, "INSERT INTO descriptors VALUES (?, ?, ?, ?)", -1,
                       &s, nullptr);
    sqlite3_bind_int(s, 1, id);
    sqlite3_bind_int(s, 2, rows);
    sqlite3_bind_int(s, 3, cols);
    sqlite3_bind_blob(s, 4, data.data(), int(data.size()), SQLITE_TRANSIENT);
    ASSERT_EQ(sqlite3_step(s), SQLITE_DONE);
    sqlite3_finalize(s);
  }
  sqlite3_close(db);
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadDatabaseImages(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ColmapDatabase, ReadsImagesByNameAndRefusesWhatIsNotSift) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "watergs_colmap_database_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string good = (dir / "good.db").string();
  WriteDatabase(
      good, {{2, "b.jpg", 3, 128}, {1, "c.jpg", 0, 128}, {5, "a.jpg", 2, 128}});
  const std::vector<DatabaseImage> images = ReadDatabaseImages(good);
  ASSERT_EQ(images.size(), 3u);
  EXPECT_EQ(images[0].name, "a.jpg");
  EXPECT_EQ(images[0].image_id, 5);
  EXPECT_EQ(images[0].descriptors.rows(), 2);
  EXPECT_EQ(images[0].descriptors(1, 2), uint8_t(5 * 31 + 130));
  EXPECT_EQ(images[1].descriptors.rows(), 3);
  EXPECT_EQ(images[2].descriptors.rows(), 0);

  const std::string wide = (dir / "wide.db").string();
  WriteDatabase(wide, {{1, "a.jpg", 4, 64}});
  EXPECT_NE(ErrorOf(wide).find(wide + ": descriptors of image_id 1 are 4 x 64"),
            std::string::npos)
      << ErrorOf(wide);
  const std::string garbage = (dir / "garbage.db").string();
  std::ofstream(garbage) << "not a database at all, but long enough to look "
                            "like a file someone might pass";
  EXPECT_NE(ErrorOf(garbage).find(garbage + ": "), std::string::npos);
  EXPECT_NE(ErrorOf((dir / "none.db").string()).find("no such file"),
            std::string::npos);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace watergs
