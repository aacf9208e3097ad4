// Binary checkpoint I/O. Layout (little-endian): magic "WGSCKPT\0", u32
// version, then the fields of TrainingCheckpoint in declaration order
// (vectors and strings as u64 length + bytes), then a u64 FNV-1a checksum of
// everything before it.
#include "gaussian/checkpoint.h"

#include <cstring>
#include <type_traits>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

constexpr char kMagic[8] = {'W', 'G', 'S', 'C', 'K', 'P', 'T', '\0'};
// Refuse absurd lengths from corrupt files before allocating.
constexpr uint64_t kMaxLength = uint64_t(1) << 36;

class Writer {
 public:
  template <typename T>
  void Pod(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    Raw(&value, sizeof(T));
  }
  template <typename T>
  void Vector(const std::vector<T>& v) {
    Pod<uint64_t>(v.size());
    Raw(v.data(), v.size() * sizeof(T));
  }
  void String(const std::string& s) {
    Pod<uint64_t>(s.size());
    Raw(s.data(), s.size());
  }
  void Raw(const void* data, size_t size) {
    bytes_.append(static_cast<const char*>(data), size);
  }
  std::string& bytes() { return bytes_; }

 private:
  std::string bytes_;
};

class Reader {
 public:
  Reader(const std::string& path, const uint8_t* data, size_t size)
      : path_(path), data_(data), size_(size) {}
  template <typename T>
  T Pod() {
    T value;
    Raw(&value, sizeof(T));
    return value;
  }
  template <typename T>
  void Vector(std::vector<T>* v) {
    const uint64_t n = Length(sizeof(T));
    v->resize(n);
    Raw(v->data(), n * sizeof(T));
  }
  void String(std::string* s) {
    const uint64_t n = Length(1);
    s->resize(n);
    Raw(s->data(), n);
  }
  void Raw(void* out, size_t size) {
    if (size > size_ - pos_) FailAt(path_, "checkpoint is truncated");
    // An empty vector's data() may be null, which memcpy must not get.
    if (size == 0) return;
    std::memcpy(out, data_ + pos_, size);
    pos_ += size;
  }
  size_t position() const { return pos_; }

 private:
  uint64_t Length(size_t element_size) {
    const uint64_t n = Pod<uint64_t>();
    if (n > kMaxLength || n * element_size > size_ - pos_) {
      FailAt(path_, "checkpoint is corrupt (bad length)");
    }
    return n;
  }
  const std::string& path_;
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

void WriteModel(Writer& w, const GaussianModel& m) {
  w.Pod<int32_t>(m.sh_degree);
  w.Vector(m.means);
  w.Vector(m.log_scales);
  w.Vector(m.quats);
  w.Vector(m.opacity_logits);
  w.Vector(m.sh_dc);
  w.Vector(m.sh_rest);
}

void ReadModel(Reader& r, const std::string& path, GaussianModel* m) {
  m->sh_degree = r.Pod<int32_t>();
  if (m->sh_degree < 0 || m->sh_degree > 3) {
    FailAt(path, "checkpoint has SH degree " + std::to_string(m->sh_degree));
  }
  r.Vector(&m->means);
  r.Vector(&m->log_scales);
  r.Vector(&m->quats);
  r.Vector(&m->opacity_logits);
  r.Vector(&m->sh_dc);
  r.Vector(&m->sh_rest);
  const size_t n = m->size();
  if (m->means.size() != 3 * n || m->log_scales.size() != 3 * n ||
      m->quats.size() != 4 * n || m->sh_dc.size() != 3 * n ||
      m->sh_rest.size() != n * m->sh_rest_stride()) {
    FailAt(path, "checkpoint model arrays have inconsistent sizes");
  }
  // A checksum-valid file with NaN parameters would poison a resumed run.
  if (const size_t bad = m->CountNonFinite(); bad > 0) {
    FailAt(path, "checkpoint model has " + std::to_string(bad) +
                     " values that are not finite");
  }
}

}  // namespace

void WriteCheckpoint(const std::string& path, const TrainingCheckpoint& c) {
  Writer w;
  w.Raw(kMagic, sizeof(kMagic));
  w.Pod<uint32_t>(kCheckpointVersion);
  w.Pod<int64_t>(c.iteration);
  w.Pod<int32_t>(c.active_sh_degree);
  w.Pod<double>(c.elapsed_seconds);
  WriteModel(w, c.model);
  for (const AdamGroupState& g : c.adam) {
    w.Vector(g.exp_avg);
    w.Vector(g.exp_avg_sq);
    w.Vector(g.exp_avg_q);
    w.Vector(g.exp_avg_sq_shared);
    w.Vector(g.exp_avg_h);
    w.Vector(g.exp_avg_sq_h);
    w.Pod<int64_t>(g.step);
  }
  w.Pod<int64_t>(c.adam_rejected);
  w.String(c.density_state);
  w.String(c.rng_state);
  w.Vector(c.view_stack);
  w.String(c.run_signature);
  const uint64_t checksum = Fnv1a64(w.bytes().data(), w.bytes().size());
  w.Pod<uint64_t>(checksum);
  AtomicWriteFile(path, w.bytes());
}

TrainingCheckpoint ReadCheckpoint(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  if (bytes.size() < sizeof(kMagic) + 4 + 8 ||
      std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    FailAt(path, "not a watergs training checkpoint");
  }
  const size_t body = bytes.size() - sizeof(uint64_t);
  uint64_t stored = 0;
  std::memcpy(&stored, bytes.data() + body, sizeof(stored));
  Reader r(path, bytes.data(), body);
  char magic[8];
  r.Raw(magic, sizeof(magic));
  const uint32_t version = r.Pod<uint32_t>();
  if (Fnv1a64(bytes.data(), body) != stored) {
    FailAt(path, "checkpoint checksum mismatch (file is corrupt)");
  }
  if (version != kCheckpointVersion && version != 1) {
    FailAt(path, "checkpoint version " + std::to_string(version) +
                     " is not supported (this build reads version " +
                     std::to_string(kCheckpointVersion) + ")");
  }
  TrainingCheckpoint c;
  c.iteration = r.Pod<int64_t>();
  c.active_sh_degree = r.Pod<int32_t>();
  c.elapsed_seconds = r.Pod<double>();
  ReadModel(r, path, &c.model);
  // Resuming evaluates SH up to this degree over the model's coefficients.
  if (c.active_sh_degree < 0 || c.active_sh_degree > c.model.sh_degree) {
    FailAt(path, "checkpoint has active SH degree " +
                     std::to_string(c.active_sh_degree) +
                     " for a model of degree " +
                     std::to_string(c.model.sh_degree));
  }
  for (AdamGroupState& g : c.adam) {
    r.Vector(&g.exp_avg);
    r.Vector(&g.exp_avg_sq);
    r.Vector(&g.exp_avg_q);
    r.Vector(&g.exp_avg_sq_shared);
    if (version >= 2) {  // version 1 had no bfloat16 moments
      r.Vector(&g.exp_avg_h);
      r.Vector(&g.exp_avg_sq_h);
    }
    g.step = r.Pod<int64_t>();
  }
  c.adam_rejected = r.Pod<int64_t>();
  r.String(&c.density_state);
  r.String(&c.rng_state);
  r.Vector(&c.view_stack);
  r.String(&c.run_signature);
  if (r.position() != body) FailAt(path, "checkpoint has trailing bytes");
  return c;
}

}  // namespace watergs
