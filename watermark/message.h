// Watermark messages: parsing what the owner types (hex, bit string, UTF-8
// text) into exactly L bits, and printing bits back.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace watergs {

// One bit per entry, 0 or 1, most significant bit of each byte/nibble first.
using Bits = std::vector<uint8_t>;

// Parses a message into exactly `num_bits` bits:
//   "hex:0a1b..." or "0x0a1b..."  4 bits per hex digit, first digit first;
//   "bits:0101..."                one bit per character;
//   "text:..." or anything else   the UTF-8 bytes, 8 bits each, MSB first.
// A message shorter than num_bits is padded with the fixed public sequence
// PaddingBits(num_bits) from its end onward (not zeros: long constant runs
// are what an unmarked decoder output tends to look like). Throws Error if the
// message is empty, malformed, or longer than num_bits.
Bits ParseMessage(const std::string& text, int num_bits);

// The formats above, for the help of the commands' --message.
inline constexpr char kMessageFormats[] =
    "hex:HEX or 0xHEX (4 bits a digit), bits:0101.. (1 bit a character), or "
    "text:TEXT (8 bits a UTF-8 byte; a message with none of these prefixes "
    "is text too). At most the decoder's bits; shorter messages are padded";

// The padding sequence: bit i = bit (i mod 64) of SplitMix64 step i / 64
// seeded with 0x5741544552475321 ("WATERGS!"). Deterministic and documented
// so any implementation can reproduce it.
Bits PaddingBits(int num_bits);

// "0101..." for display and JSON.
std::string BitsToString(const Bits& bits);
// Hex digits (bits padded with zeros to a multiple of 4 at the end).
std::string BitsToHex(const Bits& bits);
// Number of positions where a and b differ; throws Error on size mismatch.
int HammingDistance(const Bits& a, const Bits& b);
// The message as encoder inputs: bit 1 -> +1, bit 0 -> -1.
std::vector<float> BitSigns(const Bits& bits);

}  // namespace watergs
