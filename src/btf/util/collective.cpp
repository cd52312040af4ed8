// SPDX-License-Identifier: MIT
#include "btf/util/collective.h"

#include <algorithm>
#include <exception>
#include <new>
#include <tuple>

#include "btf/util/error.h"

namespace btf {

namespace {
thread_local Collective* t_current = nullptr;
}  // namespace

Collective* current_collective() {
    return t_current;
}

ScopedCollective::ScopedCollective(Collective* collective) : m_previous(t_current) {
    t_current = collective && collective->size() > 1 ? collective : nullptr;
}

ScopedCollective::~ScopedCollective() {
    t_current = m_previous;
}

std::pair<int64_t, int64_t> rank_share(int64_t count, int rank, int size) {
    const int64_t base = count / size, extra = count % size;
    const int64_t first = rank * base + std::min<int64_t>(rank, extra);
    return {first, first + base + (rank < extra ? 1 : 0)};
}

namespace detail {

std::pair<std::string, bool> current_failure() {
    try {
        throw;
    } catch (const Cancelled& e) {
        return {e.what(), true};
    } catch (const std::bad_alloc&) {
        return {"out of memory", false};
    } catch (const std::exception& e) {
        return {e.what(), false};
    } catch (...) {
        return {"unknown failure", false};
    }
}

}  // namespace detail

}  // namespace btf
