// SPDX-License-Identifier: MIT
#include "btf/util/parallel.h"

#include <tbb/global_control.h>

namespace btf {

ThreadLimit::ThreadLimit(int threads) {
    if (threads > 0)
        m_control = new tbb::global_control(tbb::global_control::max_allowed_parallelism,
                                            static_cast<size_t>(threads));
}

ThreadLimit::~ThreadLimit() {
    delete static_cast<tbb::global_control*>(m_control);
}

int worker_threads() {
    return static_cast<int>(
        tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

}  // namespace btf
