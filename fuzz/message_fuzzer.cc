// libFuzzer target: the watermark message parser (watermark/message.h). The
// first byte picks the decoder's message length (1-1021 bits), the rest is
// the text the owner typed. A parsed message must be exactly that long, hold
// only 0/1 and print back consistently.
#include "fuzz/fuzz_support.h"
#include "watermark/message.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  if (size == 0) return 0;
  const int num_bits = 1 + 4 * data[0];
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  Bits bits;
  try {
    bits = ParseMessage(text, num_bits);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e);
    return 0;
  }
  if (static_cast<int>(bits.size()) != num_bits) {
    fuzz::Finding("message of the wrong length");
  }
  for (const uint8_t bit : bits) {
    if (bit > 1) fuzz::Finding("message bit other than 0/1");
  }
  if (BitsToString(bits).size() != bits.size() ||
      BitsToHex(bits).size() != (bits.size() + 3) / 4 ||
      HammingDistance(bits, bits) != 0) {
    fuzz::Finding("message does not print back consistently");
  }
  const Bits round_trip = ParseMessage("bits:" + BitsToString(bits), num_bits);
  if (round_trip != bits) fuzz::Finding("bits: form does not round-trip");
  return 0;
}
