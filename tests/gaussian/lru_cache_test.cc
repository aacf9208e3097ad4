// Tests of the byte-bounded LRU cache (gaussian/util/lru_cache.h).
#include "gaussian/util/lru_cache.h"

#include <gtest/gtest.h>

#include <string>

namespace watergs {
namespace {

TEST(LruCache, DropsTheLeastRecentlyUsedFirstAndCountsBytes) {
  LruCache<int, std::string> cache(10);
  cache.Insert(1, "one", 4);
  cache.Insert(2, "two", 4);
  ASSERT_NE(cache.Find(1), nullptr);  // 1 is now the most recent
  cache.Insert(3, "three", 4);        // 12 > 10: drops 2, not 1
  EXPECT_EQ(cache.Find(2), nullptr);
  ASSERT_NE(cache.Find(1), nullptr);
  EXPECT_EQ(*cache.Find(1), "one");
  EXPECT_EQ(*cache.Find(3), "three");
  EXPECT_EQ(cache.size(), 2u);
  EXPECT_EQ(cache.used_bytes(), 8u);
  // One entry larger than the whole cache is not kept, and drops nothing.
  cache.Insert(4, "four", 11);
  EXPECT_EQ(cache.Find(4), nullptr);
  EXPECT_EQ(cache.size(), 2u);
  // A key already cached keeps its first value.
  cache.Insert(1, "uno", 4);
  EXPECT_EQ(*cache.Find(1), "one");
  // Room is made for an entry the size of the cache by dropping everything.
  cache.Insert(5, "five", 10);
  EXPECT_EQ(cache.size(), 1u);
  EXPECT_EQ(cache.used_bytes(), 10u);
  EXPECT_EQ(*cache.Find(5), "five");
}

}  // namespace
}  // namespace watergs
