#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace wm::world {

/// A map from small non-negative integer keys (element numbers, object indices, hash buckets) to values, whose
/// copies share everything they have not changed since. The world model is copied once per request and published
/// as an immutable snapshot; with a std::map that copy costs the whole map (about 30 ms at 100 000 elements),
/// here it costs one pointer per 4 096 keys: keys live in chunks of 64 value pointers, chunks in pages of 64 chunk
/// pointers, and a change copies one page, one chunk (64 pointers each) and the changed value.
/// Keys should be dense: the table is as long as the largest key. Not thread-safe for writing; copies may be read
/// from any thread while another copy is changed (shared values are never changed in place).
template <typename T>
class CowMap {
  static constexpr std::size_t kChunkBits = 6;
  static constexpr std::size_t kChunkSize = std::size_t{1} << kChunkBits;
  struct Chunk {
    std::array<std::shared_ptr<const T>, kChunkSize> slots;
  };
  struct Page {
    std::array<std::shared_ptr<Chunk>, kChunkSize> chunks;
  };
  static constexpr std::size_t kPageKeys = kChunkSize * kChunkSize;

 public:
  /// Iterates in key order over the present keys.
  class const_iterator {
   public:
    using value_type = std::pair<std::int64_t, const T&>;
    const_iterator(const CowMap* map, std::size_t key) : map_(map), key_(key) { skip_absent(); }
    value_type operator*() const { return {static_cast<std::int64_t>(key_), *map_->slot(key_)}; }
    const_iterator& operator++() {
      ++key_;
      skip_absent();
      return *this;
    }
    bool operator==(const const_iterator& other) const { return key_ == other.key_; }
    bool operator!=(const const_iterator& other) const { return key_ != other.key_; }

   private:
    void skip_absent() {
      const std::size_t end = map_->pages_.size() * kPageKeys;
      while (key_ < end) {
        const auto& page = map_->pages_[key_ / kPageKeys];
        if (!page) {
          key_ = (key_ / kPageKeys + 1) * kPageKeys;
          continue;
        }
        const auto& chunk = page->chunks[(key_ >> kChunkBits) & (kChunkSize - 1)];
        if (!chunk) {
          key_ = ((key_ >> kChunkBits) + 1) << kChunkBits;
          continue;
        }
        if (chunk->slots[key_ & (kChunkSize - 1)]) return;
        ++key_;
      }
      key_ = end;
    }
    const CowMap* map_;
    std::size_t key_;
  };

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  const_iterator begin() const { return {this, 0}; }
  const_iterator end() const { return {this, pages_.size() * kPageKeys}; }

  const T* find(std::int64_t key) const { return key < 0 ? nullptr : slot(static_cast<std::size_t>(key)); }
  bool contains(std::int64_t key) const { return find(key) != nullptr; }
  std::size_t count(std::int64_t key) const { return contains(key) ? 1 : 0; }
  /// @throw std::out_of_range when the key is absent.
  const T& at(std::int64_t key) const {
    const T* value = find(key);
    if (!value) throw std::out_of_range("CowMap: no key " + std::to_string(key));
    return *value;
  }

  /// Inserts or replaces. @throw std::out_of_range for a negative key.
  void put(std::int64_t key, T value) {
    if (key < 0) throw std::out_of_range("CowMap: negative key");
    const auto k = static_cast<std::size_t>(key);
    if (k / kPageKeys >= pages_.size()) pages_.resize(k / kPageKeys + 1);
    auto& slot = own_chunk(k).slots[k & (kChunkSize - 1)];
    if (!slot) ++size_;
    slot = std::make_shared<const T>(std::move(value));
  }

  /// Removes the key; false when it was absent.
  bool erase(std::int64_t key) {
    if (!contains(key)) return false;
    const auto k = static_cast<std::size_t>(key);
    own_chunk(k).slots[k & (kChunkSize - 1)].reset();
    --size_;
    return true;
  }

  void clear() {
    pages_.clear();
    size_ = 0;
  }

 private:
  const T* slot(std::size_t key) const {
    const std::size_t p = key / kPageKeys;
    if (p >= pages_.size() || !pages_[p]) return nullptr;
    const auto& chunk = pages_[p]->chunks[(key >> kChunkBits) & (kChunkSize - 1)];
    return chunk ? chunk->slots[key & (kChunkSize - 1)].get() : nullptr;
  }

  // Makes `pointer` point to a node of its own, copied first when another copy of the map shares it. use_count()
  // is exact enough here: only holders of this map's pages can raise it, and this map is not being copied while
  // it is changed.
  template <typename Node>
  static Node& own(std::shared_ptr<Node>& pointer) {
    if (!pointer)
      pointer = std::make_shared<Node>();
    else if (pointer.use_count() > 1)
      pointer = std::make_shared<Node>(*pointer);
    return *pointer;
  }

  // The chunk that holds `key` (its page exists), owned by this map.
  Chunk& own_chunk(std::size_t key) {
    return own(own(pages_[key / kPageKeys]).chunks[(key >> kChunkBits) & (kChunkSize - 1)]);
  }

  std::vector<std::shared_ptr<Page>> pages_;
  std::size_t size_ = 0;
};

}  // namespace wm::world
