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

// The owner's key scrambles the message: what is embedded and claimed is
// message XOR KeyStream(key), so the claim is a uniformly random pattern that
// no unmarked scene or decoder bias can lean towards, and the verdict's
// false-positive rate holds over the choice of key (docs/verification.md).
// KeyStream: bit i is bit (7 - i mod 8) of byte (i / 8) mod 32 of
// SHA-256("watergs-key-v1" || 0x00 || key || uint32 big-endian (i / 256)).
// Error if num_bits <= 0 or the key is empty.
Bits KeyStream(const std::string& key, int num_bits);

// message XOR KeyStream(key, message length); an empty key leaves the
// message as it is (unkeyed). Applying the same key twice gives the message.
Bits ApplyKey(const Bits& message, const std::string& key);

// The key an option names: "file:PATH" reads the first line of PATH (so the
// key stays out of shell history and process lists), anything else is the
// key itself. Error naming the file if it is missing or its first line empty.
std::string ResolveKey(const std::string& key_option);

// SHA-256 of the key's bytes in hex (`printf %s KEY | sha256sum`): what an
// owner publishes or registers when embedding, so that the claim is seen to
// be fixed before any suspect was read. Error if the key is empty.
std::string KeyFingerprint(const std::string& key);

// The formats above, for the help of the commands' --key.
inline constexpr char kKeyHelp[] =
    "Owner's secret key: the bits embedded and claimed are the message XOR a "
    "SHA-256 stream of the key, which makes the false-positive rate hold by "
    "construction (docs/verification.md). The key itself, or file:PATH (first "
    "line of PATH). Empty: unkeyed";

// "0101..." for display and JSON.
std::string BitsToString(const Bits& bits);
// Hex digits (bits padded with zeros to a multiple of 4 at the end).
std::string BitsToHex(const Bits& bits);
// Number of positions where a and b differ; throws Error on size mismatch.
int HammingDistance(const Bits& a, const Bits& b);
// The message as encoder inputs: bit 1 -> +1, bit 0 -> -1.
std::vector<float> BitSigns(const Bits& bits);

}  // namespace watergs
