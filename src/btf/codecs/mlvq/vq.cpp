// SPDX-License-Identifier: MIT
#include "btf/codecs/mlvq/vq.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::mlvq {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr size_t kMaxLength = size_t(1) << 26;
// Below this many code-vectors a linear scan beats fitting and searching an index.
constexpr size_t kMinIndexed = 64;
// The tree is rebuilt when more than max(kMinBuffer, 2√N) code-vectors wait outside it.
constexpr size_t kMinBuffer = 32;
// Code-vectors sampled for the principal subspace.
constexpr size_t kFitSample = 1024;
// Values between two checks of a partial sum against the bound.
constexpr size_t kAbandonBlock = 32;

// The squared differences of a and b summed in float with eight interleaved accumulators and a
// fixed pairwise reduction, weighted and added to `base` in double: base + w·Σ(a − b)². Returns
// +∞ as soon as a partial sum exceeds `bound` (partial sums of non-negative terms and the
// fused multiply-add are monotone, so the full value would exceed it too). Every caller uses
// this one function, kept out of line and unspecialized (noipa): brute force and the index
// compute bit-identical values, whatever contraction the compiler would choose elsewhere.
[[gnu::noipa]] double weighted_ssd(const float* a, const float* b, size_t n, double w, double base,
                                   double bound) {
    float acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    const auto add8 = [&acc](const float* x, const float* y) {
        for (int j = 0; j < 8; ++j) {
            const float d = x[j] - y[j];
            acc[j] += d * d;
        }
    };
    const auto reduce = [&acc] {
        return ((acc[0] + acc[4]) + (acc[2] + acc[6])) + ((acc[1] + acc[5]) + (acc[3] + acc[7]));
    };
    const size_t full = n & ~size_t(7);
    size_t i = 0;
    while (i < full) {
        const size_t stop = std::min(full, i + kAbandonBlock);
        for (; i < stop; i += 8) add8(a + i, b + i);
        if (i < n && std::fma(w, double(reduce()), base) > bound) return kInf;
    }
    if (i < n) {
        // The tail, zero-padded to eight lanes (zeros add nothing).
        float ta[8] = {0, 0, 0, 0, 0, 0, 0, 0}, tb[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        std::copy(a + i, a + n, ta);
        std::copy(b + i, b + n, tb);
        add8(ta, tb);
    }
    return std::fma(w, double(reduce()), base);
}

// The truncated, renormalized Gaussian window of one dimension of the vector's shape: for
// position i the taps cover positions i + first[i] .. i + first[i] + count[i] − 1.
struct AxisWindow {
    std::vector<int> first, count;
    std::vector<size_t> offset;  // into weights
    std::vector<double> weights;

    AxisWindow(uint32_t size, uint32_t radius, double sigma) {
        const int r = int(std::min<uint32_t>(radius, size));
        for (int i = 0; i < int(size); ++i) {
            const int lo = std::max(-r, -i), hi = std::min(r, int(size) - 1 - i);
            first.push_back(lo);
            count.push_back(hi - lo + 1);
            offset.push_back(weights.size());
            double sum = 0;
            for (int t = lo; t <= hi; ++t) sum += std::exp(-double(t * t) / (2 * sigma * sigma));
            for (int t = lo; t <= hi; ++t)
                weights.push_back(std::exp(-double(t * t) / (2 * sigma * sigma)) / sum);
        }
    }
};

// Filters `data` (the values of one channel, shape dims[0..count)) in place along every
// dimension with the windows of those dimensions; `line` is scratch of the largest dim.
void blur(double* data, const uint32_t* dims, const AxisWindow* windows, size_t count,
          std::vector<double>& line) {
    size_t total = 1;
    for (size_t a = 0; a < count; ++a) total *= dims[a];
    size_t outer = 1;
    for (size_t a = 0; a < count; ++a) {
        const size_t m = dims[a], stride = total / outer / m;
        const AxisWindow& win = windows[a];
        if (m > 1) {
            line.resize(m);
            for (size_t o = 0; o < outer; ++o)
                for (size_t s = 0; s < stride; ++s) {
                    double* base = data + o * m * stride + s;
                    for (size_t i = 0; i < m; ++i) line[i] = base[i * stride];
                    for (size_t i = 0; i < m; ++i) {
                        const double* w = win.weights.data() + win.offset[i];
                        const double* x = line.data() + int(i) + win.first[i];
                        double v = 0;
                        for (int t = 0; t < win.count[i]; ++t) v += w[t] * x[t];
                        base[i * stride] = v;
                    }
                }
        }
        outer *= m;
    }
}

// Sum of squares with four accumulators (vectorizable without reassociation).
double sum_squares(const double* x, size_t n) {
    double acc[4] = {0, 0, 0, 0};
    size_t i = 0;
    for (; i + 4 <= n; i += 4)
        for (int j = 0; j < 4; ++j) acc[j] += x[i + j] * x[i + j];
    for (int j = 0; i < n; ++i, ++j) acc[j] += x[i] * x[i];
    return (acc[0] + acc[2]) + (acc[1] + acc[3]);
}

}  // namespace

size_t Layout::channel_size() const {
    size_t n = 1;
    for (uint32_t d : dims) n *= d;
    return n;
}

// ---- internal state -------------------------------------------------------------------------

/// The index (see the header): PCA signatures of the code-vectors (mse) or of their windowed
/// means (mssim) in a k-d tree. Signatures are stored in blocks of kLanes, coordinate-major, so
/// that the lower bounds of a block are computed side by side in vector registers.
struct Codebook::Index {
    static constexpr uint32_t kLanes = 8;

    struct Group {
        size_t offset = 0, length = 0;
        uint32_t k = 0;
        std::vector<double> mean;     // length
        std::vector<double> basis;    // k × length, orthonormal rows
        std::vector<double> basis_t;  // length × k, the same transposed
        double radius = 0;            // max ‖c − mean‖ over the code-vectors with a signature
    };
    struct Node {
        bool leaf = true;
        uint32_t begin = 0, end = 0;  // leaf: blocks [begin, end); inner: right child is `end`
                                      // (the left one is this + 1)
    };

    std::vector<Group> groups;
    uint32_t dims = 0;       // signature length: Σ (k + 1)
    std::vector<float> sig;  // code-vector order, dims each
    size_t fitted = 0;       // code-vectors at the last fit; 0: none yet
    std::vector<Node> nodes;
    std::vector<float> node_lo, node_hi;  // the bounding box of each node's signatures
    // Blocks of kLanes signatures (dims × kLanes floats; unused lanes have id kNone): first one
    // per tree leaf, then the code-vectors added since the tree was built; with their bounding
    // boxes.
    std::vector<float> blocks, block_lo, block_hi;
    std::vector<uint32_t> block_ids;
    size_t tree_blocks = 0;
    size_t tree_count = 0;  // code-vectors 0 .. tree_count − 1 are in the tree

    size_t block_count() const { return block_ids.size() / kLanes; }

    // Signature of `values` (stored form) into out[0, dims); the centred norm per group into
    // norms (for the radius and the rounding margin).
    template <typename T>
    void signature(const T* values, double* out, double* norms,
                   std::vector<double>& scratch) const {
        uint32_t pos = 0;
        for (size_t g = 0; g < groups.size(); ++g) {
            const Group& gr = groups[g];
            const size_t n = gr.length;
            const uint32_t k = gr.k;
            scratch.resize(n);
            for (size_t i = 0; i < n; ++i) scratch[i] = double(values[gr.offset + i]) - gr.mean[i];
            norms[g] = std::sqrt(sum_squares(scratch.data(), n));
            double* c = out + pos;
            std::fill(c, c + k, 0.0);
            for (size_t i = 0; i < n; ++i) {
                const double* u = gr.basis_t.data() + i * k;
                for (uint32_t j = 0; j < k; ++j) c[j] += u[j] * scratch[i];
            }
            for (uint32_t j = 0; j < k; ++j) {
                const double* u = gr.basis.data() + size_t(j) * n;
                const double cj = c[j];
                for (size_t i = 0; i < n; ++i) scratch[i] -= cj * u[i];
            }
            out[pos + k] = std::sqrt(sum_squares(scratch.data(), n));
            pos += k + 1;
        }
    }

    // Puts code-vector `id` with signature `s` into lane `lane` of block `block`.
    void set_lane(size_t block, uint32_t lane, uint32_t id, const float* s) {
        float* b = blocks.data() + block * dims * kLanes;
        float* lo = block_lo.data() + block * dims;
        float* hi = block_hi.data() + block * dims;
        for (uint32_t j = 0; j < dims; ++j) {
            b[j * kLanes + lane] = s[j];
            lo[j] = std::min(lo[j], s[j]);
            hi[j] = std::max(hi[j], s[j]);
        }
        block_ids[block * kLanes + lane] = id;
    }
    size_t new_block() {
        blocks.resize(blocks.size() + size_t(dims) * kLanes, 0.f);
        block_lo.resize(block_lo.size() + dims, std::numeric_limits<float>::infinity());
        block_hi.resize(block_hi.size() + dims, -std::numeric_limits<float>::infinity());
        block_ids.resize(block_ids.size() + kLanes, Match::kNone);
        return block_count() - 1;
    }

    // The signature of the vector just appended (id = count − 1), into the scanned tail.
    template <typename T>
    void append(const T* values, uint32_t id, std::vector<double>& scratch) {
        std::vector<double> s(dims);
        double norms[2] = {0, 0};
        signature(values, s.data(), norms, scratch);
        for (double v : s) sig.push_back(float(v));
        for (size_t g = 0; g < groups.size(); ++g)
            groups[g].radius = std::max(groups[g].radius, norms[g]);
        const size_t tail = id - tree_count;
        const size_t block = tail % kLanes == 0 ? new_block() : block_count() - 1;
        set_lane(block, uint32_t(tail % kLanes), id, sig.data() + size_t(id) * dims);
    }

    // Principal subspaces of a sample of the indexed vectors (`count` of `length` values in
    // `data`), then every signature and the tree.
    template <typename T>
    void fit(const std::vector<T>& data, size_t count, size_t length) {
        const size_t m = std::min(count, kFitSample);
        std::vector<size_t> ids(m);
        for (size_t i = 0; i < m; ++i) ids[i] = i * count / m;
        for (Group& gr : groups) {
            Eigen::MatrixXd x(m, gr.length);
            for (size_t r = 0; r < m; ++r)
                for (size_t i = 0; i < gr.length; ++i)
                    x(r, i) = data[ids[r] * length + gr.offset + i];
            const Eigen::RowVectorXd mean = x.colwise().mean();
            x.rowwise() -= mean;
            gr.mean.assign(mean.data(), mean.data() + gr.length);
            // Top-k principal directions: from the covariance when the vectors are short, from
            // the Gram matrix of the sample when they are long. (Directions beyond the sample's
            // rank stay zero here; the QR below completes them.)
            Eigen::MatrixXd u = Eigen::MatrixXd::Zero(gr.length, gr.k);
            if (gr.length <= m) {
                const Eigen::MatrixXd cov = x.transpose() * x;
                Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(cov);
                u = eig.eigenvectors().rightCols(gr.k).rowwise().reverse();
            } else {
                const Eigen::MatrixXd gram = x * x.transpose();
                Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
                const Eigen::Index k = std::min<Eigen::Index>(gr.k, Eigen::Index(m));
                u.leftCols(k) = x.transpose() * eig.eigenvectors().rightCols(k).rowwise().reverse();
            }
            // Orthonormal to working precision whatever the conditioning (Householder Q).
            Eigen::HouseholderQR<Eigen::MatrixXd> qr(u);
            const Eigen::MatrixXd q =
                qr.householderQ() * Eigen::MatrixXd::Identity(gr.length, gr.k);
            gr.basis.resize(size_t(gr.k) * gr.length);
            gr.basis_t.resize(size_t(gr.k) * gr.length);
            for (uint32_t j = 0; j < gr.k; ++j)
                for (size_t i = 0; i < gr.length; ++i)
                    gr.basis[size_t(j) * gr.length + i] = gr.basis_t[i * gr.k + j] = q(i, j);
            gr.radius = 0;
        }
        sig.clear();
        sig.reserve(count * dims);
        std::vector<double> s(dims), scratch;
        for (size_t c = 0; c < count; ++c) {
            double norms[2] = {0, 0};
            signature(data.data() + c * length, s.data(), norms, scratch);
            for (double v : s) sig.push_back(float(v));
            for (size_t g = 0; g < groups.size(); ++g)
                groups[g].radius = std::max(groups[g].radius, norms[g]);
        }
        fitted = count;
        build_tree(count);
    }

    // After vector `id` of `data` was appended: its signature, and a refit or a new tree when due.
    template <typename T>
    void grow(const std::vector<T>& data, uint32_t id, size_t length,
              std::vector<double>& scratch) {
        const size_t count = size_t(id) + 1;
        if (fitted == 0) {
            if (count >= kMinIndexed) fit(data, count, length);
            return;
        }
        append(data.data() + size_t(id) * length, id, scratch);
        if (count >= 4 * fitted)
            fit(data, count, length);
        else if (count - tree_count >
                 std::max<size_t>(kMinBuffer, size_t(2 * std::sqrt(double(count)))))
            build_tree(count);
    }

    // Calls consider(id) for every indexed vector whose signature bound does not exclude it
    // from the ball of squared radius radius2() around `point` (weighted distance with
    // weight[g] on group g), nearer ones first. radius2() is read again after every consider()
    // that returns true (the ball shrinks as better matches are found). Nothing inside the ball
    // is skipped: the bounds carry a margin for the rounding of every signature (header).
    template <typename T, typename Radius2, typename Consider>
    void search(const T* point, const double weight[2], Query& q, Radius2&& radius2,
                Consider&& consider, uint64_t& bounded) const;

    void build_tree(size_t count) {
        std::vector<uint32_t> perm(count);
        std::iota(perm.begin(), perm.end(), 0u);
        nodes.clear();
        node_lo.clear();
        node_hi.clear();
        blocks.clear();
        block_lo.clear();
        block_hi.clear();
        block_ids.clear();
        build_node(perm, 0, uint32_t(count));
        tree_blocks = block_count();
        tree_count = count;
    }

    uint32_t build_node(std::vector<uint32_t>& perm, uint32_t begin, uint32_t end) {
        const uint32_t id = uint32_t(nodes.size());
        nodes.push_back(Node{});
        node_lo.resize(node_lo.size() + dims);
        node_hi.resize(node_hi.size() + dims);
        // The bounding box; a split along its longest side.
        int32_t best_dim = -1;
        float best_spread = 0;
        for (uint32_t d = 0; d < dims; ++d) {
            float lo = std::numeric_limits<float>::infinity(), hi = -lo;
            for (uint32_t p = begin; p < end; ++p) {
                const float v = sig[size_t(perm[p]) * dims + d];
                lo = std::min(lo, v);
                hi = std::max(hi, v);
            }
            node_lo[size_t(id) * dims + d] = lo;
            node_hi[size_t(id) * dims + d] = hi;
            if (hi - lo > best_spread) best_spread = hi - lo, best_dim = int32_t(d);
        }
        if (end - begin <= kLanes || best_dim < 0) {
            // A leaf: one block, or several when more than kLanes signatures are identical.
            const uint32_t first = uint32_t(block_count());
            for (uint32_t p = begin; p < end; ++p) {
                if ((p - begin) % kLanes == 0) new_block();
                set_lane(block_count() - 1, (p - begin) % kLanes, perm[p],
                         sig.data() + size_t(perm[p]) * dims);
            }
            nodes[id] = Node{true, first, uint32_t(block_count())};
            return id;
        }
        const uint32_t mid = begin + (end - begin) / 2;
        const auto key = [&](uint32_t c) {
            return std::make_pair(sig[size_t(c) * dims + size_t(best_dim)], c);
        };
        std::nth_element(perm.begin() + begin, perm.begin() + mid, perm.begin() + end,
                         [&](uint32_t a, uint32_t b) { return key(a) < key(b); });
        build_node(perm, begin, mid);
        const uint32_t right = build_node(perm, mid, end);
        nodes[id] = Node{false, begin, right};
        return id;
    }
};

/// The SSIM machinery of Measure::mssim.
struct Codebook::Ssim {
    std::vector<AxisWindow> windows;  // per dim of the layout
    size_t outliers = 0;              // k of the percentile
    double c1 = 0, c2 = 0;
    // Windowed means and variances of the stored code-vectors, in double: the covariance
    // E[xc] − μx·μc cancels, and float means would cost SSIM ~1e-6.
    std::vector<double> means, vars;
    // For the index over the means: the smallest mean stored (the index needs every mean ≥ 0)
    // and per channel group the largest squared mean.
    double min_mean = kInf;
    double max_mean2[2] = {0, 0};
};

/// A prepared query and the scratch of one search (one per thread).
struct Codebook::Query {
    std::vector<float> values;  // stored form
    double scale = 1;
    double weight[2] = {1, 1};  // per channel group: s² for luminance, 1 otherwise
    // mse index
    std::vector<double> sig, coord_weight, scratch;
    std::vector<float> sig_f, coord_weight_f;
    // mssim
    std::vector<double> raw, mean, var, rows, exy, line, dis, point;
};

template <typename T, typename Radius2, typename Consider>
void Codebook::Index::search(const T* point, const double weight[2], Query& q, Radius2&& radius2,
                             Consider&& consider, uint64_t& bounded) const {
    q.sig.resize(dims);
    q.coord_weight.resize(dims);
    q.sig_f.resize(dims);
    q.coord_weight_f.resize(dims);
    double norms[2] = {0, 0};
    signature(point, q.sig.data(), norms, q.scratch);
    // Rounding margin: e bounds the error of each signature coordinate difference in weighted
    // units (the float storage of both signatures and the double arithmetic that made them);
    // rho the relative error of the float lower bounds of a block.
    double e = 0;
    uint32_t pos = 0;
    for (size_t g = 0; g < groups.size(); ++g) {
        const Group& gr = groups[g];
        const double eg =
            (0x1p-23 + double(gr.length * (gr.k + 2) + 16) * 0x1p-51) * (gr.radius + norms[g]);
        e = std::max(e, std::sqrt(weight[g]) * eg);
        for (uint32_t j = 0; j <= gr.k; ++j) q.coord_weight[pos + j] = weight[g];
        pos += gr.k + 1;
    }
    for (uint32_t j = 0; j < dims; ++j) {
        q.sig_f[j] = float(q.sig[j]);
        q.coord_weight_f[j] = float(q.coord_weight[j]);
    }
    const double rho = double(dims + 8) * 0x1p-23;
    const double e_sqrt_k = e * std::sqrt(double(dims));
    // Boxes (double) are pruned above t, block lanes (float) above t_lane.
    double t = 0;
    float t_lane = 0;
    const auto set_bound = [&] {
        const double r = e_sqrt_k + std::sqrt(radius2());
        t = r * r * (1 + 1e-9);
        t_lane = float(t * (1 + rho) * (1 + 0x1p-22));
    };
    set_bound();
    const double* qs = q.sig.data();
    const double* cw = q.coord_weight.data();
    const float* qf = q.sig_f.data();
    const float* wf = q.coord_weight_f.data();
    // The lower bounds of the kLanes signatures of a block side by side, then the survivors.
    const auto scan_block = [&](size_t block) {
        bounded += kLanes;
        const float* b = blocks.data() + block * dims * kLanes;
        float lb[kLanes] = {0, 0, 0, 0, 0, 0, 0, 0};
        for (uint32_t j = 0; j < dims; ++j) {
            const float qj = qf[j], wj = wf[j];
            const float* bj = b + j * kLanes;
            for (uint32_t l = 0; l < kLanes; ++l) {
                const float d = qj - bj[l];
                lb[l] += wj * d * d;
            }
        }
        const uint32_t* ids = block_ids.data() + block * kLanes;
        for (uint32_t l = 0; l < kLanes; ++l)
            if (!(lb[l] > t_lane) && ids[l] != Match::kNone && consider(ids[l])) set_bound();
    };
    // Weighted squared distance from the query to a bounding box: a lower bound for every
    // signature inside.
    const auto box_distance = [&](const float* lo, const float* hi) {
        double d = 0;
        for (uint32_t j = 0; j < dims; ++j) {
            const double gap = std::max({0.0, double(lo[j]) - qs[j], qs[j] - double(hi[j])});
            d += cw[j] * gap * gap;
        }
        return d;
    };
    // Depth first, the nearer child first, pruning boxes beyond the ball.
    const auto visit = [&](const auto& self, uint32_t node_id, double distance) -> void {
        if (distance > t) return;
        const Node& node = nodes[node_id];
        if (node.leaf) {
            for (uint32_t b = node.begin; b < node.end; ++b) scan_block(b);
            return;
        }
        const uint32_t left = node_id + 1, right = node.end;
        const double dl = box_distance(node_lo.data() + size_t(left) * dims,
                                       node_hi.data() + size_t(left) * dims);
        const double dr = box_distance(node_lo.data() + size_t(right) * dims,
                                       node_hi.data() + size_t(right) * dims);
        if (dl <= dr) {
            self(self, left, dl);
            self(self, right, dr);
        } else {
            self(self, right, dr);
            self(self, left, dl);
        }
    };
    if (!nodes.empty()) visit(visit, 0, box_distance(node_lo.data(), node_hi.data()));
    for (size_t b = tree_blocks; b < block_count(); ++b)
        if (!(box_distance(block_lo.data() + b * dims, block_hi.data() + b * dims) > t))
            scan_block(b);
}

// ---- construction ---------------------------------------------------------------------------

Codebook::Codebook(CodebookOptions options) : m_options(std::move(options)) {
    const std::string& name = m_options.name;
    const Layout& layout = m_options.layout;
    check(!layout.dims.empty(), "mlvq code-book {}: the layout has no dimensions", name);
    size_t n = layout.channels;
    check(layout.channels > 0, "mlvq code-book {}: the layout has 0 channels", name);
    for (uint32_t d : layout.dims) {
        check(d > 0, "mlvq code-book {}: a dimension of the layout is 0", name);
        check(n <= kMaxLength / d, "mlvq code-book {}: vectors longer than {} values", name,
              kMaxLength);
        n *= d;
    }
    m_length = n;
    check(m_options.index_dims > 0, "mlvq code-book {}: index_dims must be at least 1", name);
    check_threshold(m_options.threshold);
    const size_t nc = layout.channel_size();
    if (m_options.kind == Kind::luminance) {
        m_groups[0] = nc;
        m_groups[1] = m_length - nc;
    } else {
        m_groups[0] = m_length;
    }

    // mse indexes the code-vectors, mssim their windowed means.
    m_index = std::make_unique<Index>();
    size_t offset = 0;
    for (size_t len : m_groups) {
        if (len == 0) continue;
        Index::Group g;
        g.offset = offset;
        g.length = len;
        g.k = uint32_t(std::min<size_t>(m_options.index_dims, len));
        m_index->dims += g.k + 1;
        m_index->groups.push_back(std::move(g));
        offset += len;
    }
    if (m_options.measure == Measure::mssim) {
        const SsimOptions& s = m_options.ssim;
        check(std::isfinite(s.dynamic_range) && s.dynamic_range > 0,
              "mlvq code-book {}: SSIM dynamic range must be positive, not {}", name,
              s.dynamic_range);
        check(std::isfinite(s.k1) && s.k1 > 0 && std::isfinite(s.k2) && s.k2 > 0,
              "mlvq code-book {}: SSIM constants K1 = {}, K2 = {} must be positive", name, s.k1,
              s.k2);
        check(std::isfinite(s.sigma) && s.sigma > 0,
              "mlvq code-book {}: SSIM window sigma must be positive, not {}", name, s.sigma);
        check(s.percentile > 0 && s.percentile <= 100,
              "mlvq code-book {}: SSIM percentile must be in (0, 100], not {}", name, s.percentile);
        m_ssim = std::make_unique<Ssim>();
        for (uint32_t d : layout.dims) m_ssim->windows.emplace_back(d, s.radius, s.sigma);
        m_ssim->outliers = std::min(
            m_length - 1, size_t(std::floor((100 - s.percentile) / 100 * double(m_length) + 1e-9)));
        m_ssim->c1 = (s.k1 * s.dynamic_range) * (s.k1 * s.dynamic_range);
        m_ssim->c2 = (s.k2 * s.dynamic_range) * (s.k2 * s.dynamic_range);
    }
}

Codebook::~Codebook() = default;
Codebook::Codebook(Codebook&&) noexcept = default;
Codebook& Codebook::operator=(Codebook&&) noexcept = default;

void Codebook::check_threshold(double threshold) const {
    check(threshold >= 0, "mlvq code-book {}: threshold must be ≥ 0, not {}", m_options.name,
          threshold);
}

size_t Codebook::size() const {
    return m_data.size() / m_length;
}

std::span<const float> Codebook::vector(uint32_t i) const {
    check(i < size(), "mlvq code-book {}: no code-vector {} (size {})", m_options.name, i, size());
    return {m_data.data() + size_t(i) * m_length, m_length};
}

void Codebook::set_threshold(double threshold) {
    check_threshold(threshold);
    m_options.threshold = threshold;
}

void Codebook::reserve(size_t code_vectors) {
    m_data.reserve(code_vectors * m_length);
    if (m_ssim) {
        m_ssim->means.reserve(code_vectors * m_length);
        m_ssim->vars.reserve(code_vectors * m_length);
    }
    m_index->sig.reserve(code_vectors * m_index->dims);
}

// ---- queries --------------------------------------------------------------------------------

// Out of line and unspecialized for the same reason as weighted_ssd: the stored form of a query
// is the same bits on every path.
[[gnu::noipa]] void Codebook::prepare(std::span<const float> values, Query& q) const {
    const std::string& name = m_options.name;
    check(values.size() == m_length, "mlvq code-book {}: query has {} values, expected {}", name,
          values.size(), m_length);
    for (size_t i = 0; i < m_length; ++i)
        check(std::isfinite(values[i]), "mlvq code-book {}: query value {} is not finite ({})",
              name, i, values[i]);
    q.values.assign(values.begin(), values.end());
    q.scale = 1;
    q.weight[0] = q.weight[1] = 1;
    if (m_options.kind == Kind::luminance) {
        const size_t nc = m_groups[0];
        double s = 0;
        for (size_t i = 0; i < nc; ++i) s += std::abs(double(values[i]));
        q.scale = s;
        q.weight[0] = s * s;
        for (size_t i = 0; i < nc; ++i)
            q.values[i] = s > 0 ? float(double(values[i]) / s) : float(1.0 / double(nc));
    }
    if (m_ssim) {
        const Layout& layout = m_options.layout;
        const size_t nc = layout.channel_size();
        q.raw.assign(values.begin(), values.end());
        q.mean = q.raw;
        q.var.resize(m_length);
        for (size_t i = 0; i < m_length; ++i) q.var[i] = q.raw[i] * q.raw[i];
        for (uint32_t c = 0; c < layout.channels; ++c) {
            blur(q.mean.data() + c * nc, layout.dims.data(), m_ssim->windows.data(),
                 layout.dims.size(), q.line);
            blur(q.var.data() + c * nc, layout.dims.data(), m_ssim->windows.data(),
                 layout.dims.size(), q.line);
        }
        for (size_t i = 0; i < m_length; ++i)
            q.var[i] = std::max(0.0, q.var[i] - q.mean[i] * q.mean[i]);
    }
}

double Codebook::mse_sum(const Query& q, uint32_t i, double bound) const {
    const float* c = m_data.data() + size_t(i) * m_length;
    const double first = weighted_ssd(q.values.data(), c, m_groups[0], q.weight[0], 0.0, bound);
    if (m_groups[1] == 0 || first > bound) return first;
    return weighted_ssd(q.values.data() + m_groups[0], c + m_groups[0], m_groups[1], q.weight[1],
                        first, bound);
}

// Exact filter before the windowed comparison: 1 − SSIM ≥ 1 − |l| because |cs| ≤ 1, and l needs
// only the local means. True if more than k values must exceed `bound`. Written without
// division and counted in blocks of 8 so that it vectorizes; the margin (1e-9) covers the
// difference between this test and the division in mssim_measure.
bool Codebook::mssim_rejects(const Query& q, uint32_t id, double bound) const {
    const Ssim& ss = *m_ssim;
    // |l| < c  ⇔  1 − |l| > bound + 1e-9
    const double c = 1 - (bound + 1e-9);
    if (!(c > 0)) return false;
    const Layout& layout = m_options.layout;
    const size_t nc = layout.channel_size();
    const double* cmean = ss.means.data() + size_t(id) * m_length;
    const double* qmean = q.mean.data();
    const double c1 = ss.c1;
    size_t over = 0;
    for (uint32_t ch = 0; ch < layout.channels; ++ch) {
        const double s = m_options.kind == Kind::luminance && ch == 0 ? q.scale : 1.0;
        const size_t begin = ch * nc, end = (ch + 1) * nc;
        const auto count = [&](size_t j) {
            const double x = qmean[j], y = s * cmean[j];
            return size_t(std::abs(2 * x * y + c1) < c * (x * x + y * y + c1));
        };
        size_t i = begin;
        for (; i + 8 <= end; i += 8) {
            size_t block = 0;
            for (size_t j = i; j < i + 8; ++j) block += count(j);
            over += block;
            if (over > ss.outliers) return true;
        }
        for (; i < end; ++i) over += count(i);
        if (over > ss.outliers) return true;
    }
    return false;
}

// The percentile of 1 − SSIM between the query and code-vector i (with the query's scale on
// the luminance channel), or +∞ as soon as more than k values exceed `bound`.
[[gnu::noipa]] double Codebook::mssim_measure(Query& q, uint32_t id, double bound) const {
    const Ssim& ss = *m_ssim;
    const Layout& layout = m_options.layout;
    const size_t nc = layout.channel_size();
    const size_t base = size_t(id) * m_length;
    const double* cmean = ss.means.data() + base;
    const double* cvar = ss.vars.data() + base;
    const double c1 = ss.c1, c2 = ss.c2;
    const auto channel_scale = [&](uint32_t ch) {
        return m_options.kind == Kind::luminance && ch == 0 ? q.scale : 1.0;
    };
    const uint32_t d0 = layout.dims[0];
    const size_t rest = nc / d0;
    const AxisWindow& w0 = ss.windows[0];
    const size_t slots = std::min<size_t>(d0, 2 * size_t(m_options.ssim.radius) + 1);
    q.rows.resize(slots * rest);
    q.exy.resize(rest);
    q.dis.clear();
    size_t over = 0;
    for (uint32_t ch = 0; ch < layout.channels; ++ch) {
        const double s = channel_scale(ch);
        const double* x = q.raw.data() + ch * nc;
        const float* c = m_data.data() + base + ch * nc;
        uint32_t computed = 0;  // rows of the windowed product x·c computed so far
        for (uint32_t o = 0; o < d0; ++o) {
            const int first = int(o) + w0.first[o], taps = w0.count[o];
            // The rows within the window of row o, filtered along the inner dimensions.
            while (int(computed) < first + taps) {
                double* row = q.rows.data() + (computed % slots) * rest;
                const size_t at = size_t(computed) * rest;
                for (size_t j = 0; j < rest; ++j) row[j] = x[at + j] * double(c[at + j]);
                blur(row, layout.dims.data() + 1, ss.windows.data() + 1, layout.dims.size() - 1,
                     q.line);
                ++computed;
            }
            const double* w = w0.weights.data() + w0.offset[o];
            std::fill(q.exy.begin(), q.exy.end(), 0.0);
            for (int t = 0; t < taps; ++t) {
                const double* row = q.rows.data() + (size_t(first + t) % slots) * rest;
                for (size_t j = 0; j < rest; ++j) q.exy[j] += w[t] * row[j];
            }
            for (size_t j = 0; j < rest; ++j) {
                const size_t i = ch * nc + size_t(o) * rest + j;
                const double mx = q.mean[i], vx = q.var[i];
                const double mc = cmean[i], my = s * mc, vy = s * s * cvar[i];
                const double cov = s * (q.exy[j] - mx * mc);
                const double l =
                    std::clamp((2 * mx * my + c1) / (mx * mx + my * my + c1), -1.0, 1.0);
                const double cs = std::clamp((2 * cov + c2) / (vx + vy + c2), -1.0, 1.0);
                const double d = 1 - l * cs;
                q.dis.push_back(d);
                if (d > bound && ++over > ss.outliers) return kInf;
            }
        }
    }
    const auto kth = q.dis.end() - 1 - ptrdiff_t(ss.outliers);
    std::nth_element(q.dis.begin(), kth, q.dis.end());
    return *kth;
}

Match Codebook::search(Query& q, double threshold, bool brute_force, SearchStats* stats) const {
    check_threshold(threshold);
    if (stats) ++stats->searches, stats->codebook += size();
    if (!m_ssim) {
        // Sums of squares against threshold · n (the MSE times the number of values).
        Match m = search_mse(q, threshold * double(m_length), brute_force, stats);
        if (m) m.error /= double(m_length);
        return m;
    }
    return search_mssim(q, threshold, brute_force, stats);
}

Match Codebook::search_mse(Query& q, double bound0, bool brute_force, SearchStats* stats) const {
    Match best;
    best.scale = q.scale;
    const size_t count = size();
    if (count == 0) return best;
    uint64_t compared = 0, bounded = 0;
    double best_err = kInf;
    uint32_t best_id = Match::kNone;
    // Full comparison; true if `id` is the new best.
    const auto consider = [&](uint32_t id) {
        ++compared;
        const double err = mse_sum(q, id, std::min(bound0, best_err));
        if (err <= bound0 && (err < best_err || (err == best_err && id < best_id))) {
            best_err = err;
            best_id = id;
            return true;
        }
        return false;
    };

    const Index& idx = *m_index;
    const bool all_zero = q.weight[0] == 0 && (m_groups[1] == 0 || q.weight[1] == 0);
    if (all_zero && !brute_force) {
        // A black luminance slice: every code-vector reconstructs it exactly (error 0), and the
        // lowest index wins the tie.
        best_err = 0, best_id = 0, compared = 1;
    } else if (brute_force || idx.fitted == 0) {
        for (uint32_t id = 0; id < count; ++id) consider(id);
    } else {
        // A full comparison's float sum of squares is within a factor 1 ± gamma of the exact
        // one, so none within bound0 (or the best so far) lies outside this ball.
        size_t longest = 0;
        for (const Index::Group& g : idx.groups) longest = std::max(longest, g.length);
        const double gamma = double(longest + 16) * 0x1p-23;
        idx.search(
            q.values.data(), q.weight, q,
            [&] { return std::min(bound0, best_err) * (1 + 2 * gamma); }, consider, bounded);
    }
    if (stats) stats->compared += compared, stats->bounded += bounded;
    if (best_id != Match::kNone) best.index = best_id, best.error = best_err;
    return best;
}

Match Codebook::search_mssim(Query& q, double threshold, bool brute_force,
                             SearchStats* stats) const {
    Match best;
    best.scale = q.scale;
    const size_t count = size();
    uint64_t compared = 0, bounded = 0;
    // True if `id` is the new best.
    const auto consider = [&](uint32_t id) {
        const double bound = std::min(threshold, best.error);
        if (mssim_rejects(q, id, bound)) return false;
        ++compared;
        const double d = mssim_measure(q, id, bound);
        if (d <= threshold && (d < best.error || (d == best.error && id < best.index))) {
            best.index = id, best.error = d;
            return true;
        }
        return false;
    };
    const Ssim& ss = *m_ssim;
    const Index& idx = *m_index;
    bool indexed = !brute_force && idx.fitted > 0 && ss.min_mean >= 0;
    for (size_t i = 0; indexed && i < m_length; ++i) indexed = q.mean[i] >= 0;
    if (brute_force) {
        for (uint32_t id = 0; id < count; ++id) {
            ++compared;
            const double d = mssim_measure(q, id, kInf);
            if (d <= threshold && d < best.error) best.index = id, best.error = d;
        }
    } else if (!indexed) {
        for (uint32_t id = 0; id < count; ++id) consider(id);
    } else {
        // Every mean non-negative, so l ≥ 0, and a value with 1 − SSIM ≤ B has
        // 1 − l = (a − b)² / (a² + b² + C1) ≤ B for its local means a (query) and b (the scaled
        // code-vector); an outlier has (a − b)² ≤ a² + b². Summed over the values, with the
        // k outliers' squares bounded by the query's k largest a² and k times the code-book's
        // largest b², and ‖b‖ ≤ ‖a‖ + ‖a − b‖, every candidate within B has ‖a − b‖ ≤ R:
        //   R = (B√A + √(B²A + (1 − B)(B(2A + nC1) + (1 − B)(Xk + kY)))) / (1 − B),
        // A = ‖a‖², Xk = the k largest a², Y = the largest b². ‖a − b‖ is the weighted distance
        // between the query's normalized means and the code-vector's stored means: an index
        // range query over the means.
        const size_t k = ss.outliers;
        q.dis.assign(m_length, 0.0);
        for (size_t i = 0; i < m_length; ++i) q.dis[i] = q.mean[i] * q.mean[i];
        const double a2 = std::accumulate(q.dis.begin(), q.dis.end(), 0.0);
        double xk = 0;
        if (k > 0) {
            std::nth_element(q.dis.begin(), q.dis.end() - ptrdiff_t(k), q.dis.end());
            xk = std::accumulate(q.dis.end() - ptrdiff_t(k), q.dis.end(), 0.0);
        }
        double y = 0;
        for (size_t g = 0; g < 2; ++g) y = std::max(y, q.weight[g] * ss.max_mean2[g]);
        const double nc1 = double(m_length) * ss.c1;
        const auto radius2 = [&] {
            // The margin covers the rounding of the computed dissimilarities.
            const double b = std::min(threshold, best.error) * (1 + 1e-9) + 1e-12;
            if (!(b < 1)) return kInf;
            const double r = (b * std::sqrt(a2) +
                              std::sqrt(b * b * a2 + (1 - b) * (b * (2 * a2 + nc1) +
                                                                (1 - b) * (xk + double(k) * y)))) /
                             (1 - b);
            return r * r * (1 + 1e-9);
        };
        // The query's means in the stored (normalized) units of each group.
        q.point = q.mean;
        if (m_options.kind == Kind::luminance)
            for (size_t i = 0; i < m_groups[0]; ++i)
                q.point[i] = q.scale > 0 ? q.mean[i] / q.scale : 0.0;
        idx.search(q.point.data(), q.weight, q, radius2, consider, bounded);
    }
    if (stats) stats->compared += compared, stats->bounded += bounded;
    return best;
}

Match Codebook::find(std::span<const float> query) const {
    return find(query, m_options.threshold);
}

Match Codebook::find(std::span<const float> query, double threshold, SearchStats* stats) const {
    thread_local Query q;
    prepare(query, q);
    return search(q, threshold, false, stats);
}

Match Codebook::find_brute_force(std::span<const float> query, double threshold) const {
    thread_local Query q;
    prepare(query, q);
    return search(q, threshold, true, nullptr);
}

std::vector<Match> Codebook::find_batch(std::span<const float> queries) const {
    return find_batch(queries, m_options.threshold);
}

std::vector<Match> Codebook::find_batch(std::span<const float> queries, double threshold) const {
    check(queries.size() % m_length == 0,
          "mlvq code-book {}: batch of {} values is not a whole number of {}-value queries",
          m_options.name, queries.size(), m_length);
    check_threshold(threshold);
    const size_t count = queries.size() / m_length;
    std::vector<Match> out(count);
    parallel_chunks(0, int64_t(count), 64, [&](int64_t begin, int64_t end) {
        Query q;
        for (int64_t i = begin; i < end; ++i) {
            prepare(queries.subspan(size_t(i) * m_length, m_length), q);
            out[size_t(i)] = search(q, threshold, false, nullptr);
        }
    });
    return out;
}

// ---- growth ---------------------------------------------------------------------------------

Match Codebook::add(std::span<const float> values) {
    check(size() < size_t(Match::kNone), "mlvq code-book {}: full ({} code-vectors)",
          m_options.name, size());
    thread_local Query q;
    prepare(values, q);
    const uint32_t id = uint32_t(size());
    m_data.insert(m_data.end(), q.values.begin(), q.values.end());
    if (m_ssim) {
        // Windowed means and variances of the stored form, per channel.
        const Layout& layout = m_options.layout;
        const size_t nc = layout.channel_size();
        std::vector<double> mean(q.values.begin(), q.values.end()), sq(m_length);
        for (size_t i = 0; i < m_length; ++i) sq[i] = mean[i] * mean[i];
        for (uint32_t c = 0; c < layout.channels; ++c) {
            blur(mean.data() + c * nc, layout.dims.data(), m_ssim->windows.data(),
                 layout.dims.size(), q.line);
            blur(sq.data() + c * nc, layout.dims.data(), m_ssim->windows.data(), layout.dims.size(),
                 q.line);
        }
        for (size_t i = 0; i < m_length; ++i) {
            m_ssim->means.push_back(mean[i]);
            m_ssim->vars.push_back(std::max(0.0, sq[i] - mean[i] * mean[i]));
        }
    }
    if (m_ssim) {
        // The index over the means (see search_mssim) and what its radius needs.
        Ssim& ss = *m_ssim;
        const double* mean = ss.means.data() + size_t(id) * m_length;
        for (size_t i = 0; i < m_length; ++i) {
            ss.min_mean = std::min(ss.min_mean, mean[i]);
            const size_t g = i < m_groups[0] ? 0 : 1;
            ss.max_mean2[g] = std::max(ss.max_mean2[g], mean[i] * mean[i]);
        }
        m_index->grow(ss.means, id, m_length, q.scratch);
    } else {
        m_index->grow(m_data, id, m_length, q.scratch);
    }
    Match m;
    m.index = id;
    m.added = true;
    m.scale = q.scale;
    m.error = m_ssim ? mssim_measure(q, id, kInf) : mse_sum(q, id, kInf) / double(m_length);
    return m;
}

Match Codebook::find_or_add(std::span<const float> query) {
    const Match m = find(query);
    return m ? m : add(query);
}

void Codebook::rebuild_index() {
    if (size() < kMinIndexed) return;
    if (m_ssim)
        m_index->fit(m_ssim->means, size(), m_length);
    else
        m_index->fit(m_data, size(), m_length);
}

}  // namespace btf::mlvq
