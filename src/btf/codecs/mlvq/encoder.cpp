// SPDX-License-Identifier: MIT
#include "btf/codecs/mlvq/encoder.h"

#include <cmath>
#include <limits>

#include "btf/util/error.h"

namespace btf::mlvq {

namespace {

CodebookOptions book(const char* name, std::vector<uint32_t> dims, uint32_t channels, Kind kind,
                     const EncoderOptions& o, double threshold) {
    CodebookOptions b;
    b.name = name;
    b.layout.dims = std::move(dims);
    b.layout.channels = channels;
    b.kind = kind;
    b.measure = o.measure;
    b.threshold = o.measure == Measure::mssim ? o.threshold : threshold;
    b.ssim = o.ssim;
    return b;
}

double sum(const float* v, size_t n) {
    double s = 0;
    for (size_t i = 0; i < n; ++i) s += std::abs(double(v[i]));
    return s;
}

// The two chromaticity planes of n samples one after the other: a chroma code-vector.
std::vector<float> planes_of(const float* c1, const float* c2, size_t n) {
    std::vector<float> v(c1, c1 + n);
    v.insert(v.end(), c2, c2 + n);
    return v;
}

}  // namespace

Encoder::Encoder(const EncoderOptions& o)
    : m_options(o),
      m_p4(book("P4",
                {uint32_t(o.grid.n_phi_v), uint32_t(o.grid.n_theta_v), uint32_t(o.grid.n_alpha),
                 uint32_t(o.grid.n_beta)},
                3, Kind::luminance, o, o.threshold)),
      m_p3(book("P3",
                {uint32_t(o.grid.n_theta_v), uint32_t(o.grid.n_alpha), uint32_t(o.grid.n_beta)}, 3,
                Kind::luminance, o, o.threshold * o.level_factor)),
      m_m(book("M", {uint32_t(o.grid.n_alpha), uint32_t(o.grid.n_beta)}, 3, Kind::luminance, o,
               o.threshold * std::pow(o.level_factor, 2))),
      m_p2(book("P2", {uint32_t(o.grid.n_alpha), uint32_t(o.grid.n_beta)}, 1, Kind::luminance, o,
                o.threshold * std::pow(o.level_factor, 3))),
      m_p1(book("P1", {uint32_t(o.grid.n_beta)}, 1, Kind::luminance, o,
                o.threshold * std::pow(o.level_factor, 4))),
      m_i2(book("I2", {uint32_t(o.grid.n_alpha), uint32_t(o.grid.n_beta)}, 2, Kind::chromaticity, o,
                o.threshold_i2)),
      m_i1(book("I1", {uint32_t(o.grid.n_beta)}, 2, Kind::chromaticity, o, o.threshold_i1)),
      m_c(book("C", {1}, 2, Kind::chromaticity, o, o.threshold_c)) {
    o.grid.validate();
    check(o.threshold >= 0 && o.level_factor > 0 && o.level_factor <= 1,
          "mlvq: threshold {} and level factor {} (need ≥ 0 and in (0, 1])", o.threshold,
          o.level_factor);
    m_books.grid = o.grid;
    m_books.colour = o.colour;
}

void Encoder::scale_thresholds(double factor) {
    for (Codebook* b : {&m_p4, &m_p3, &m_m, &m_p2, &m_p1, &m_i2, &m_i1, &m_c})
        b->set_threshold(b->options().threshold * factor);
}

void Encoder::freeze() {
    m_p4.rebuild_index();
}

IndexScale Encoder::insert(std::span<const float> texel) {
    check(texel.size() == texel_length(), "mlvq: a texel of {} values, expected {}", texel.size(),
          texel_length());
    const size_t n4 = size_t(m_options.grid.samples());
    const double mass = sum(texel.data(), n4);
    const uint32_t index = p4(texel.data());
    return {index, float(mass)};
}

std::vector<IndexScale> Encoder::nearest(std::span<const float> texels) const {
    check(texels.size() % texel_length() == 0, "mlvq: {} values are not whole texels of {}",
          texels.size(), texel_length());
    check(m_p4.size() > 0, "mlvq: nearest() before any texel was inserted");
    const std::vector<Match> matches =
        m_p4.find_batch(texels, std::numeric_limits<double>::infinity());
    std::vector<IndexScale> out(matches.size());
    for (size_t t = 0; t < matches.size(); ++t)
        out[t] = {matches[t].index, float(matches[t].scale)};
    return out;
}

// Each level: search; otherwise decompose, then add the reconstruction from the children (what
// the decoder produces) as the new code-vector.

// The luminance levels P4, P3, P2: `query` holds `parts` consecutive slices per plane (plane 0
// luminance); unmatched, each slice goes to child(slice, plane stride) and the new entry keeps
// (child index, the slice's share of the luminance sum), in `table` as the decoder reads it.

template <typename Child>
uint32_t Encoder::split(Codebook& book, const Codebook& children, std::vector<IndexScale>& table,
                        std::span<const float> query, int parts, Child child) {
    const Match found = book.find(query);
    if (found) return found.index;
    const size_t planes = book.options().layout.channels;
    const size_t n = query.size() / planes, part = n / size_t(parts);
    const double total = sum(query.data(), n);
    std::vector<float> recon(query.size());
    std::vector<IndexScale> entries(static_cast<size_t>(parts));
    for (int k = 0; k < parts; ++k) {
        const float* sub = query.data() + size_t(k) * part;
        const uint32_t index = child(sub, n);
        const float scale = total > 0 ? float(sum(sub, part) / total) : 0.0f;
        entries[size_t(k)] = {index, scale};
        const std::span<const float> v = children.vector(index);
        for (size_t p = 0; p < planes; ++p)
            for (size_t s = 0; s < part; ++s)
                recon[p * n + size_t(k) * part + s] = (p == 0 ? scale : 1.0f) * v[p * part + s];
    }
    const Match added = book.add(recon);
    table.insert(table.end(), entries.begin(), entries.end());
    return added.index;
}

uint32_t Encoder::p4(const float* texel) {
    const MlvqGrid& g = m_options.grid;
    return split(m_p4, m_p3, m_books.p4, std::span<const float>(texel, texel_length()), g.n_phi_v,
                 [this](const float* sub, size_t stride) { return p3(sub, stride); });
}

uint32_t Encoder::p3(const float* slice, size_t stride) {
    const MlvqGrid& g = m_options.grid;
    const size_t n3 = size_t(g.n_theta_v) * g.n_alpha * g.n_beta;
    std::vector<float> query(3 * n3);
    for (int p = 0; p < 3; ++p)
        std::copy(slice + p * stride, slice + p * stride + n3, query.begin() + p * n3);
    return split(m_p3, m_m, m_books.p3, query, g.n_theta_v,
                 [this](const float* sub, size_t s) { return merge(sub, s); });
}

uint32_t Encoder::merge(const float* slice, size_t stride) {
    const MlvqGrid& g = m_options.grid;
    const size_t n2 = size_t(g.n_alpha) * g.n_beta;
    std::vector<float> query(3 * n2);
    for (int p = 0; p < 3; ++p)
        std::copy(slice + p * stride, slice + p * stride + n2, query.begin() + p * n2);
    const Match found = m_m.find(query);
    if (found) return found.index;
    const std::array<uint32_t, 2> pair = {p2(query.data()),
                                          i2(query.data() + n2, query.data() + 2 * n2)};
    if (const auto it = m_pairs.find(pair); it != m_pairs.end()) return it->second;
    std::vector<float> recon(3 * n2);
    const std::span<const float> y = m_p2.vector(pair[0]), c = m_i2.vector(pair[1]);
    std::copy(y.begin(), y.end(), recon.begin());
    std::copy(c.begin(), c.end(), recon.begin() + n2);
    const Match added = m_m.add(recon);
    m_books.m.push_back(pair);
    m_pairs.emplace(pair, added.index);
    return added.index;
}

uint32_t Encoder::p2(const float* y) {
    const MlvqGrid& g = m_options.grid;
    return split(m_p2, m_p1, m_books.p2, std::span<const float>(y, size_t(g.n_alpha) * g.n_beta),
                 g.n_alpha, [this](const float* sub, size_t) { return p1(sub); });
}

uint32_t Encoder::p1(const float* y) {
    const size_t nb = size_t(m_options.grid.n_beta);
    const Match m = m_p1.find_or_add(std::span<const float>(y, nb));
    if (m.added) {
        const std::span<const float> v = m_p1.vector(m.index);
        m_books.p1.insert(m_books.p1.end(), v.begin(), v.end());
    }
    return m.index;
}

uint32_t Encoder::i2(const float* c1, const float* c2) {
    const MlvqGrid& g = m_options.grid;
    const size_t nb = size_t(g.n_beta), n2 = nb * g.n_alpha;
    const Match found = m_i2.find(planes_of(c1, c2, n2));
    if (found) return found.index;
    std::vector<float> recon(2 * n2);
    for (int i = 0; i < g.n_alpha; ++i) {
        const uint32_t child = i1(c1 + size_t(i) * nb, c2 + size_t(i) * nb);
        m_books.i2.push_back(child);
        const std::span<const float> v = m_i1.vector(child);
        for (size_t j = 0; j < nb; ++j) {
            recon[size_t(i) * nb + j] = v[j];
            recon[n2 + size_t(i) * nb + j] = v[nb + j];
        }
    }
    return m_i2.add(recon).index;
}

uint32_t Encoder::i1(const float* c1, const float* c2) {
    const size_t nb = size_t(m_options.grid.n_beta);
    const Match found = m_i1.find(planes_of(c1, c2, nb));
    if (found) return found.index;
    std::vector<float> recon(2 * nb);
    for (size_t j = 0; j < nb; ++j) {
        const uint32_t child = c(c1[j], c2[j]);
        m_books.i1.push_back(child);
        recon[j] = m_books.c[child][0];
        recon[nb + j] = m_books.c[child][1];
    }
    return m_i1.add(recon).index;
}

uint32_t Encoder::c(float c1, float c2) {
    const float query[2] = {c1, c2};
    const Match m = m_c.find_or_add(query);
    if (m.added) {
        const std::span<const float> v = m_c.vector(m.index);
        m_books.c.push_back({v[0], v[1]});
    }
    return m.index;
}

}  // namespace btf::mlvq
