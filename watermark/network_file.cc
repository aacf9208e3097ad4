// Reading and writing the network container (format in network_file.h).
#include "watermark/network_file.h"

#include <algorithm>
#include <cstring>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

constexpr char kMagic[8] = {'W', 'G', 'S', 'N', 'N', 'E', 'T', '\0'};

template <typename T>
void Put(std::string* out, T value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

void PutString(std::string* out, const std::string& s) {
  Put<uint32_t>(out, uint32_t(s.size()));
  out->append(s);
}

// Bounds-checked cursor over the payload; any overrun means truncation.
class Reader {
 public:
  Reader(const std::string& path, const uint8_t* data, size_t size)
      : path_(path), data_(data), size_(size) {}
  template <typename T>
  T Get() {
    T value;
    Need(sizeof(T));
    std::memcpy(&value, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  std::string GetString() {
    const uint32_t length = Get<uint32_t>();
    if (length > 4096) FailAt(path_, "corrupted (name longer than 4096 bytes)");
    Need(length);
    std::string s(reinterpret_cast<const char*>(data_ + pos_), length);
    pos_ += length;
    // Names are identifiers; a control character (a newline would split the
    // one-line errors that quote the name) means corruption.
    for (const char c : s) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
        FailAt(path_, "corrupted (name with a control character)");
    }
    return s;
  }
  void GetFloats(float* out, size_t count) {
    if (count > (size_ - pos_) / sizeof(float)) Need(size_ + 1);
    // An empty tensor's data() may be null, which memcpy must not get.
    if (count == 0) return;
    std::memcpy(out, data_ + pos_, count * sizeof(float));
    pos_ += count * sizeof(float);
  }
  size_t remaining() const { return size_ - pos_; }

 private:
  void Need(size_t bytes) {
    if (bytes > size_ - pos_) FailAt(path_, "truncated network file");
  }
  const std::string& path_;
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

}  // namespace

int64_t NetworkFile::Meta(const std::string& key,
                          const std::string& path) const {
  for (const auto& [k, v] : meta)
    if (k == key) return v;
  FailAt(path, "missing field " + key);
}

const TensorRecord* NetworkFile::Find(const std::string& name) const {
  for (const TensorRecord& t : tensors)
    if (t.name == name) return &t;
  return nullptr;
}

namespace {

// Version 1's checksum: FNV-1a from a mistyped offset basis.
uint64_t LegacyFnv1a64(const uint8_t* data, size_t size) {
  uint64_t hash = 1469598103934665603ull;
  for (size_t i = 0; i < size; ++i) {
    hash ^= data[i];
    hash *= 1099511628211ull;
  }
  return hash;
}

}  // namespace

std::string SerializeNetworkFile(const NetworkFile& file) {
  std::string out(kMagic, sizeof(kMagic));
  Put<uint32_t>(&out, kNetworkFileVersion);
  PutString(&out, file.kind);
  Put<uint32_t>(&out, uint32_t(file.meta.size()));
  for (const auto& [key, value] : file.meta) {
    PutString(&out, key);
    Put<int64_t>(&out, value);
  }
  Put<uint32_t>(&out, uint32_t(file.tensors.size()));
  for (const TensorRecord& t : file.tensors) {
    PutString(&out, t.name);
    Put<uint32_t>(&out, uint32_t(t.shape.size()));
    for (int d : t.shape) Put<int32_t>(&out, d);
    out.append(reinterpret_cast<const char*>(t.values.data()),
               t.values.size() * sizeof(float));
  }
  Put<uint64_t>(
      &out, Fnv1a64(reinterpret_cast<const uint8_t*>(out.data()), out.size()));
  return out;
}

NetworkFile ParseNetworkFile(const std::string& path,
                             const std::vector<uint8_t>& bytes) {
  if (bytes.size() < sizeof(kMagic) + 4 + 8) {
    if (bytes.size() >= sizeof(kMagic) &&
        std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
      FailAt(path, "not a watergs network file (bad magic)");
    FailAt(path, "truncated network file (" + std::to_string(bytes.size()) +
                     " bytes)");
  }
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    FailAt(path, "not a watergs network file (bad magic)");
  Reader header(path, bytes.data() + sizeof(kMagic), 4);
  const uint32_t version = header.Get<uint32_t>();
  if (version != 1 && version != kNetworkFileVersion)
    FailAt(path, "unsupported network file version " + std::to_string(version) +
                     " (this build reads 1 to " +
                     std::to_string(kNetworkFileVersion) + ")");
  const size_t payload = bytes.size() - 8;
  uint64_t stored;
  std::memcpy(&stored, bytes.data() + payload, 8);
  const uint64_t checksum = version == 1 ? LegacyFnv1a64(bytes.data(), payload)
                                         : Fnv1a64(bytes.data(), payload);
  if (checksum != stored)
    FailAt(path,
           "checksum mismatch: the network file is corrupted or truncated");

  Reader in(path, bytes.data() + sizeof(kMagic) + 4,
            payload - sizeof(kMagic) - 4);
  NetworkFile file;
  file.kind = in.GetString();
  const uint32_t meta_count = in.Get<uint32_t>();
  if (meta_count > 1024) FailAt(path, "corrupted (too many fields)");
  for (uint32_t i = 0; i < meta_count; ++i) {
    std::string key = in.GetString();
    file.meta.emplace_back(std::move(key), in.Get<int64_t>());
  }
  const uint32_t tensor_count = in.Get<uint32_t>();
  if (tensor_count > 100000) FailAt(path, "corrupted (too many tensors)");
  for (uint32_t i = 0; i < tensor_count; ++i) {
    TensorRecord t;
    t.name = in.GetString();
    const uint32_t rank = in.Get<uint32_t>();
    if (rank > 8) FailAt(path, "corrupted (tensor " + t.name + " of rank > 8)");
    // The product saturates: eight large dims must not wrap around to a
    // small count that the size check below would accept.
    constexpr size_t kCountCap = size_t(1) << 39;
    size_t count = 1;
    for (uint32_t r = 0; r < rank; ++r) {
      const int32_t d = in.Get<int32_t>();
      if (d < 0 || d > (1 << 24))
        FailAt(path, "corrupted (tensor " + t.name + ")");
      t.shape.push_back(d);
      count = std::min(count * size_t(d), kCountCap);
    }
    if (count > in.remaining() / sizeof(float))
      FailAt(path, "truncated network file (tensor " + t.name + ")");
    t.values.resize(count);
    in.GetFloats(t.values.data(), count);
    file.tensors.push_back(std::move(t));
  }
  if (in.remaining() != 0) FailAt(path, "corrupted (trailing bytes)");
  return file;
}

void WriteNetworkFile(const std::string& path, const NetworkFile& file) {
  AtomicWriteFile(path, SerializeNetworkFile(file));
}

NetworkFile ReadNetworkFile(const std::string& path) {
  return ParseNetworkFile(path, ReadFileBytes(path));
}

}  // namespace watergs
