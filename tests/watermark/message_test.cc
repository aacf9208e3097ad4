#include "watermark/message.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>

#include "gaussian/util/error.h"
#include "watermark/verification.h"

namespace watergs {
namespace {

TEST(Message, HexBitsAndTextGiveTheSameBits) {
  // 'A' = 0x41 = 0100 0001.
  const Bits from_text = ParseMessage("A", 8);
  EXPECT_EQ(BitsToString(from_text), "01000001");
  EXPECT_EQ(ParseMessage("hex:41", 8), from_text);
  EXPECT_EQ(ParseMessage("0x41", 8), from_text);
  EXPECT_EQ(ParseMessage("bits:01000001", 8), from_text);
  EXPECT_EQ(ParseMessage("text:A", 8), from_text);
  EXPECT_EQ(BitsToHex(from_text), "41");
}

TEST(Message, BitSignsMapOneToPlusOneAndZeroToMinusOne) {
  EXPECT_EQ(BitSigns(Bits{1, 0, 0, 1}), (std::vector<float>{1, -1, -1, 1}));
  EXPECT_TRUE(BitSigns(Bits{}).empty());
}

TEST(Message, Utf8TextUsesItsBytes) {
  // U+00E9 is 0xC3 0xA9 in UTF-8.
  EXPECT_EQ(BitsToHex(ParseMessage("\xC3\xA9", 16)), "c3a9");
}

TEST(Message, ShortMessagesArePaddedWithThePublicSequence) {
  const Bits padding = PaddingBits(48);
  const Bits bits = ParseMessage("hex:ff", 48);
  ASSERT_EQ(bits.size(), 48u);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(bits[i], 1);
  for (int i = 8; i < 48; ++i) EXPECT_EQ(bits[i], padding[i]);
  // The padding is balanced enough not to look like a constant message.
  int ones = 0;
  for (uint8_t b : padding) ones += b;
  EXPECT_GT(ones, 12);
  EXPECT_LT(ones, 36);
  EXPECT_EQ(PaddingBits(48), padding);
}

TEST(Message, RefusesMalformedAndOverlongMessages) {
  for (const char* bad : {"", "hex:", "hex:0g", "0xzz", "bits:0102", "bits:"}) {
    EXPECT_THROW(ParseMessage(bad, 48), Error) << bad;
  }
  EXPECT_THROW(ParseMessage("hex:0123456789abc", 48), Error);
  EXPECT_NO_THROW(ParseMessage("hex:0123456789ab", 48));
  EXPECT_THROW(ParseMessage("seven!!", 48), Error);
}

TEST(Message, HammingDistanceCountsDifferences) {
  EXPECT_EQ(HammingDistance(ParseMessage("bits:0110", 4),
                            ParseMessage("bits:0011", 4)),
            2);
  EXPECT_THROW(HammingDistance(Bits(3), Bits(4)), Error);
}

// Exact tail count sum_{k >= matching} C(n, k) by integer Pascal's
// triangle, independent of the lgamma sum (exact for n <= 126).
unsigned __int128 TailCount(int matching, int n) {
  std::vector<unsigned __int128> row(n + 1, 0);
  row[0] = 1;
  for (int i = 1; i <= n; ++i) {
    for (int k = i; k > 0; --k) row[k] += row[k - 1];
  }
  unsigned __int128 count = 0;
  for (int k = matching; k <= n; ++k) count += row[k];
  return count;
}

long double ExactTail(int matching, int n) {
  return static_cast<long double>(TailCount(matching, n)) / std::pow(2.0L, n);
}

// Largest error count e with P[X >= n - e] <= 10^-6, decided in integers:
// count * 10^6 <= 2^n, i.e. count <= floor(2^n / 10^6) (no rounding, no
// overflow).
int ExactMaxErrorsAtOnePerMillion(int n) {
  const unsigned __int128 limit = (static_cast<unsigned __int128>(1) << n) /
                                  static_cast<unsigned __int128>(1000000);
  int best = -1;
  for (int e = 0; e <= n; ++e) {
    if (TailCount(n - e, n) > limit) break;
    best = e;
  }
  return best;
}

TEST(Verification, PValueMatchesExactBinomialTail) {
  // Relative tolerance: the tail reaches 2^-n (8.7e-19 at n = 60), where an
  // absolute one would accept anything. Each term is exp of a sum of three
  // lgamma values below 190 (double spacing 3e-14 there), so the sum is
  // good to ~1e-13 relative; 1e-11 leaves a margin and still catches a
  // dropped or doubled term, which changes the tail by >= 2^-n / tail.
  for (int n : {8, 16, 32, 48, 60, 100}) {
    for (int m = 0; m <= n; ++m) {
      const long double exact = ExactTail(m, n);
      const double p = BinomialTailPValue(m, n);
      EXPECT_LE(std::abs(static_cast<long double>(p) - exact), 1e-11L * exact)
          << m << "/" << n << ": " << p << " vs " << double(exact);
    }
  }
  EXPECT_DOUBLE_EQ(BinomialTailPValue(0, 48), 1.0);
  EXPECT_THROW(BinomialTailPValue(49, 48), Error);
}

TEST(Verification, RandomMessagesOfUnmarkedModelsAreRarelyPresent) {
  // Simulates unmarked decoders: uniformly random bits. The empirical
  // false-positive rate at a loose 1e-2 threshold must be close to (and not
  // above) the nominal one; at the default threshold none may fire.
  std::mt19937_64 rng(2024);
  std::bernoulli_distribution coin(0.5);
  const Bits claimed = ParseMessage("hex:a5a5a5a5a5a5", 48);
  int loose = 0, strict = 0;
  const int trials = 20000;
  for (int t = 0; t < trials; ++t) {
    Bits decoded(48);
    for (auto& b : decoded) b = coin(rng);
    const double p =
        BinomialTailPValue(48 - HammingDistance(claimed, decoded), 48);
    loose += p <= 1e-2;
    strict += Decide(p, {}) == Verdict::kPresent;
  }
  EXPECT_LE(loose, trials * 0.01 * 1.3);
  EXPECT_EQ(strict, 0);
}

TEST(Verification, VerdictsAndThresholds) {
  EXPECT_EQ(Decide(1e-9, {}), Verdict::kPresent);
  EXPECT_EQ(Decide(0.5, {}), Verdict::kAbsent);
  EXPECT_EQ(Decide(1e-4, {}), Verdict::kInconclusive);
  // At the thresholds themselves: present at p = 1e-6 (p <= present_p),
  // inconclusive at p = 0.01 (absent only above it); one ulp further each
  // way flips the verdict.
  const VerificationThresholds t;
  ASSERT_EQ(t.present_p, 1e-6);
  ASSERT_EQ(t.absent_p, 1e-2);
  EXPECT_EQ(Decide(1e-6, t), Verdict::kPresent);
  EXPECT_EQ(Decide(std::nextafter(1e-6, 1.0), t), Verdict::kInconclusive);
  EXPECT_EQ(Decide(1e-2, t), Verdict::kInconclusive);
  EXPECT_EQ(Decide(std::nextafter(1e-2, 1.0), t), Verdict::kAbsent);
  EXPECT_EQ(Decide(std::nextafter(1e-2, 0.0), t), Verdict::kInconclusive);
}

TEST(Verification, MaxErrorsForPresenceMatchesTheExactCounts) {
  // The figures the README quotes, worked out by hand from exact binomial
  // sums: at 48 bits, 7 wrong bits give p = 3.1e-7 and 8 give 1.65e-6.
  EXPECT_EQ(MaxErrorsForPresence(48, 1e-6), 7);
  EXPECT_EQ(MaxErrorsForPresence(19, 1e-6), -1);  // 2^-19 = 1.9e-6
  EXPECT_EQ(MaxErrorsForPresence(20, 1e-6), 0);   // 2^-20 = 9.5e-7
  EXPECT_EQ(MaxErrorsForPresence(32, 1e-6), 2);
  EXPECT_EQ(MaxErrorsForPresence(64, 1e-6), 13);
  EXPECT_EQ(MaxErrorsForPresence(96, 1e-6), 24);
  // Every length from 1 to 120 against the integer decision.
  for (int n = 1; n <= 120; ++n) {
    EXPECT_EQ(MaxErrorsForPresence(n, 1e-6), ExactMaxErrorsAtOnePerMillion(n))
        << n << " bits";
  }
  // present_p exactly at a tail value counts as present (<=), one ulp
  // below it does not.
  const double p7 = BinomialTailPValue(48 - 7, 48);
  EXPECT_EQ(MaxErrorsForPresence(48, p7), 7);
  EXPECT_EQ(MaxErrorsForPresence(48, std::nextafter(p7, 0.0)), 6);
}

// Expected streams computed with Python's hashlib (an independent SHA-256):
// hashlib.sha256(b"watergs-key-v1\0" + key + block.to_bytes(4, "big")).
TEST(MessageKey, KeyStreamIsTheDocumentedSha256Stream) {
  EXPECT_EQ(BitsToString(KeyStream("owner secret", 48)),
            "110101010110010110110000111001101001010110111100");
  // Bits 250..299 cross from block 0 into block 1.
  EXPECT_EQ(BitsToString(KeyStream("k", 300)).substr(250),
            "01000001000001100001001001010001101011000010100101");
}

TEST(MessageKey, ApplyingAKeyTwiceGivesTheMessageAndNoKeyChangesNothing) {
  const Bits message = ParseMessage("text:WGS-26", 48);
  const Bits keyed = ApplyKey(message, "owner secret");
  EXPECT_GT(HammingDistance(keyed, message), 10);
  EXPECT_EQ(ApplyKey(keyed, "owner secret"), message);
  EXPECT_EQ(ApplyKey(message, ""), message);
  EXPECT_NE(ApplyKey(message, "owner secreT"), keyed);
  EXPECT_THROW(KeyStream("", 48), Error);
}

TEST(MessageKey, KeyedClaimsAreFairCoinsPerBit) {
  // Over many keys every bit of a fixed (very unbalanced) message is 1 about
  // half the time: what makes the binomial null hold over keys.
  const Bits zeros(48, 0);
  std::vector<int> ones(48, 0);
  const int keys = 4000;
  for (int k = 0; k < keys; ++k) {
    const Bits keyed = ApplyKey(zeros, "key-" + std::to_string(k));
    for (int i = 0; i < 48; ++i) ones[i] += keyed[i];
  }
  // 4 sigma of Binomial(4000, 1/2) is 126.
  for (int i = 0; i < 48; ++i) EXPECT_NEAR(ones[i], keys / 2, 126) << i;
}

TEST(MessageKey, AKeyFileGivesItsFirstLine) {
  const std::string path =
      ::testing::TempDir() + "/message_test_key_" + std::to_string(getpid());
  {
    std::ofstream out(path);
    out << "secret from file\r\nsecond line\n";
  }
  EXPECT_EQ(ResolveKey("file:" + path), "secret from file");
  EXPECT_EQ(ResolveKey("plain key"), "plain key");
  {
    std::ofstream out(path);
    out << "\n";
  }
  EXPECT_THROW(ResolveKey("file:" + path), Error);
  std::remove(path.c_str());
  try {
    ResolveKey("file:" + path);
    FAIL() << "a missing key file was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
  }
}

}  // namespace
}  // namespace watergs
