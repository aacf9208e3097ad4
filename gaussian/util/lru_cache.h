// A cache bounded in bytes that drops the least recently used entry first:
// decoded photos and the input model's renders, which at users' sizes (1 MP,
// hundreds of views) would not fit in memory all at once. Not thread-safe:
// callers that share one lock around it.
#pragma once

#include <cstddef>
#include <list>
#include <unordered_map>
#include <utility>

namespace watergs {

// Key: hashable; Value: copyable (a shared_ptr keeps copies cheap). Each
// entry's size is given on insertion.
template <typename Key, typename Value>
class LruCache {
 public:
  explicit LruCache(size_t capacity_bytes) : capacity_(capacity_bytes) {}

  // The cached value (now the most recent), or nullptr when absent.
  const Value* Find(const Key& key) {
    const auto it = entries_.find(key);
    if (it == entries_.end()) return nullptr;
    order_.splice(order_.begin(), order_, it->second.position);
    return &it->second.value;
  }

  // Keeps `value` unless it alone exceeds the capacity or `key` is cached,
  // dropping the least recently used entries until it fits.
  void Insert(const Key& key, Value value, size_t bytes) {
    if (bytes > capacity_ || entries_.count(key)) return;
    while (used_ + bytes > capacity_ && !order_.empty()) {
      const auto oldest = entries_.find(order_.back());
      used_ -= oldest->second.bytes;
      entries_.erase(oldest);
      order_.pop_back();
    }
    order_.push_front(key);
    entries_.emplace(key, Entry{std::move(value), bytes, order_.begin()});
    used_ += bytes;
  }

  size_t size() const { return entries_.size(); }
  size_t used_bytes() const { return used_; }

 private:
  struct Entry {
    Value value;
    size_t bytes;
    // Its place in order_ (most recent first).
    typename std::list<Key>::iterator position;
  };
  size_t capacity_;
  size_t used_ = 0;
  std::list<Key> order_;
  std::unordered_map<Key, Entry> entries_;
};

}  // namespace watergs
