#include "watermark/message.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gaussian/error.h"
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

// Exact tail by integer Pascal's triangle, independent of the lgamma sum.
long double ExactTail(int matching, int n) {
  std::vector<unsigned long long> row(n + 1, 0);
  row[0] = 1;
  for (int i = 1; i <= n; ++i) {
    for (int k = i; k > 0; --k) row[k] += row[k - 1];
  }
  unsigned long long count = 0;
  for (int k = matching; k <= n; ++k) count += row[k];
  return static_cast<long double>(count) / std::pow(2.0L, n);
}

TEST(Verification, PValueMatchesExactBinomialTail) {
  for (int n : {8, 16, 32, 48, 60}) {
    for (int m = 0; m <= n; ++m) {
      const double exact = static_cast<double>(ExactTail(m, n));
      EXPECT_NEAR(BinomialTailPValue(m, n), exact, 1e-12 + 1e-9 * exact)
          << m << "/" << n;
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
  const int e = MaxErrorsForPresence(48, 1e-6);
  EXPECT_LE(BinomialTailPValue(48 - e, 48), 1e-6);
  EXPECT_GT(BinomialTailPValue(48 - e - 1, 48), 1e-6);
}

}  // namespace
}  // namespace watergs
