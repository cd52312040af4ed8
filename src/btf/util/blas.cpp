// SPDX-License-Identifier: MIT
#include "btf/util/blas.h"

#include <cblas.h>

#include <climits>
#include <cstdlib>
#include <mutex>

#include "btf/util/error.h"

// OpenBLAS's own entry points (declared by its cblas.h too, but not by every cblas.h).
extern "C" {
char* openblas_get_corename(void);
char* openblas_get_config(void);
int openblas_get_num_threads(void);
void openblas_set_num_threads(int threads);
}

namespace btf::blas {

std::string kernel() {
    return openblas_get_corename();
}

std::string description() {
    std::string out = openblas_get_config();
    out += ", kernel " + kernel();
    if (const char* forced = std::getenv("OPENBLAS_CORETYPE"))
        out += std::string(" (OPENBLAS_CORETYPE=") + forced + ")";
    return out;
}

namespace {
std::mutex serial_mutex;
int serial_users = 0;
int saved_threads = 1;
}  // namespace

SerialBlas::SerialBlas() {
    const std::lock_guard lock(serial_mutex);
    if (serial_users++ == 0) {
        saved_threads = openblas_get_num_threads();
        if (saved_threads != 1) openblas_set_num_threads(1);
    }
}

SerialBlas::~SerialBlas() {
    const std::lock_guard lock(serial_mutex);
    if (--serial_users == 0 && saved_threads != 1) openblas_set_num_threads(saved_threads);
}

void sgemm(bool transpose_a, bool transpose_b, int64_t m, int64_t n, int64_t k, const float* a,
           int64_t lda, const float* b, int64_t ldb, float beta, float* c, int64_t ldc) {
    for (int64_t v : {m, n, k, lda, ldb, ldc})
        if (v > INT_MAX) fail("matrix product: dimension {} exceeds the BLAS's 32-bit range", v);
    if (m == 0 || n == 0) return;
    cblas_sgemm(CblasRowMajor, transpose_a ? CblasTrans : CblasNoTrans,
                transpose_b ? CblasTrans : CblasNoTrans, int(m), int(n), int(k), 1.0f, a, int(lda),
                b, int(ldb), beta, c, int(ldc));
}

}  // namespace btf::blas
