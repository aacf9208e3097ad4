#include "watermark/message.h"

#include <openssl/sha.h>

#include <cctype>
#include <fstream>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

bool StartsWith(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  const char lower =
      static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower >= 'a' && lower <= 'f') return lower - 'a' + 10;
  return -1;
}

Bits ParseHex(const std::string& digits, const std::string& original) {
  Bits bits;
  for (char c : digits) {
    const int v = HexValue(c);
    if (v < 0)
      Fail("message `" + Printable(original) + "`: `" +
           Printable(std::string(1, c)) + "` is not a hex digit");
    for (int b = 3; b >= 0; --b) bits.push_back((v >> b) & 1);
  }
  return bits;
}

Bits ParseBitString(const std::string& digits, const std::string& original) {
  Bits bits;
  for (char c : digits) {
    if (c != '0' && c != '1') {
      Fail("message `" + Printable(original) + "`: `" +
           Printable(std::string(1, c)) + "` is not 0 or 1");
    }
    bits.push_back(c == '1');
  }
  return bits;
}

Bits ParseText(const std::string& text) {
  Bits bits;
  for (unsigned char c : text) {
    for (int b = 7; b >= 0; --b) bits.push_back((c >> b) & 1);
  }
  return bits;
}

uint64_t SplitMix64(uint64_t* state) {
  uint64_t z = (*state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace

Bits PaddingBits(int num_bits) {
  Bits bits;
  uint64_t state = 0x5741544552475321ULL;
  uint64_t word = 0;
  for (int i = 0; i < num_bits; ++i) {
    if (i % 64 == 0) word = SplitMix64(&state);
    bits.push_back((word >> (i % 64)) & 1);
  }
  return bits;
}

Bits ParseMessage(const std::string& text, int num_bits) {
  if (num_bits <= 0) Fail("message length must be positive");
  Bits bits;
  // What the limit is in the units the message was typed in.
  std::string limit;
  const std::string n = std::to_string(num_bits);
  if (StartsWith(text, "hex:")) {
    bits = ParseHex(text.substr(4), text);
    limit = std::to_string(num_bits / 4) + " hex digits";
  } else if (StartsWith(text, "0x") || StartsWith(text, "0X")) {
    bits = ParseHex(text.substr(2), text);
    limit = std::to_string(num_bits / 4) + " hex digits";
  } else if (StartsWith(text, "bits:")) {
    bits = ParseBitString(text.substr(5), text);
    limit = n + " bits";
  } else {
    bits = ParseText(StartsWith(text, "text:") ? text.substr(5) : text);
    // A character outside ASCII takes 2-4 of the bytes.
    limit = std::to_string(num_bits / 8) + " characters of ASCII text (" +
            std::to_string(num_bits / 8) + " bytes of UTF-8)";
  }
  if (bits.empty()) Fail("message `" + Printable(text) + "` is empty");
  if (static_cast<int>(bits.size()) > num_bits) {
    Fail("message `" + Printable(text) + "` needs " +
         std::to_string(bits.size()) + " bits but the decoder reads " + n +
         ": at most " + limit);
  }
  const Bits padding = PaddingBits(num_bits);
  for (size_t i = bits.size(); i < static_cast<size_t>(num_bits); ++i) {
    bits.push_back(padding[i]);
  }
  return bits;
}

Bits KeyStream(const std::string& key, int num_bits) {
  if (num_bits <= 0) Fail("key stream length must be positive");
  if (key.empty()) Fail("the key is empty");
  Bits bits;
  bits.reserve(num_bits);
  const std::string prefix = std::string("watergs-key-v1") + '\0' + key;
  for (uint32_t block = 0; static_cast<int>(bits.size()) < num_bits; ++block) {
    std::string input = prefix;
    for (int shift = 24; shift >= 0; shift -= 8) {
      input.push_back(static_cast<char>((block >> shift) & 0xff));
    }
    unsigned char digest[SHA256_DIGEST_LENGTH];
    SHA256(reinterpret_cast<const unsigned char*>(input.data()), input.size(),
           digest);
    for (int i = 0; i < 8 * SHA256_DIGEST_LENGTH &&
                    static_cast<int>(bits.size()) < num_bits;
         ++i) {
      bits.push_back((digest[i / 8] >> (7 - i % 8)) & 1);
    }
  }
  return bits;
}

Bits ApplyKey(const Bits& message, const std::string& key) {
  if (key.empty() || message.empty()) return message;
  const Bits stream = KeyStream(key, static_cast<int>(message.size()));
  Bits keyed(message.size());
  for (size_t i = 0; i < message.size(); ++i) {
    keyed[i] = (message[i] != 0) != (stream[i] != 0);
  }
  return keyed;
}

std::string KeyFingerprint(const std::string& key) {
  if (key.empty()) Fail("the key is empty");
  unsigned char digest[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(key.data()), key.size(),
         digest);
  static const char* kDigits = "0123456789abcdef";
  std::string hex;
  for (unsigned char byte : digest) {
    hex.push_back(kDigits[byte >> 4]);
    hex.push_back(kDigits[byte & 15]);
  }
  return hex;
}

std::string ResolveKey(const std::string& key_option) {
  if (!StartsWith(key_option, "file:")) return key_option;
  const std::string path = key_option.substr(5);
  std::ifstream in(path);
  if (!in) Fail(path + ": cannot read the key file");
  std::string line;
  std::getline(in, line);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line.empty()) Fail(path + ": the key file's first line is empty");
  return line;
}

std::string BitsToString(const Bits& bits) {
  std::string s;
  for (uint8_t b : bits) s.push_back(b ? '1' : '0');
  return s;
}

std::string BitsToHex(const Bits& bits) {
  static const char* kDigits = "0123456789abcdef";
  std::string s;
  for (size_t i = 0; i < bits.size(); i += 4) {
    int v = 0;
    for (size_t b = 0; b < 4; ++b) {
      v = (v << 1) | (i + b < bits.size() ? bits[i + b] : 0);
    }
    s.push_back(kDigits[v]);
  }
  return s;
}

int HammingDistance(const Bits& a, const Bits& b) {
  if (a.size() != b.size()) {
    Fail("cannot compare a " + std::to_string(a.size()) +
         "-bit message with a " + std::to_string(b.size()) + "-bit one");
  }
  int d = 0;
  for (size_t i = 0; i < a.size(); ++i) d += (a[i] != 0) != (b[i] != 0);
  return d;
}

std::vector<float> BitSigns(const Bits& bits) {
  std::vector<float> signs(bits.size());
  for (size_t i = 0; i < bits.size(); ++i) signs[i] = bits[i] ? 1.f : -1.f;
  return signs;
}

}  // namespace watergs
