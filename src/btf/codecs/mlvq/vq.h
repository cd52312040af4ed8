// SPDX-License-Identifier: MIT
#pragma once
/// The vector-quantization core of the mlvq codec (Havran, Filip, Myszkowski 2010, §4.2–§4.4 and
/// §5.1): a code-book of fixed-length float vectors that grows by the paper's threshold rule
/// ("pruning", §4.2): a query is answered by its most similar code-vector when that one is within
/// the threshold, and otherwise (find_or_add) becomes a code-vector itself. The multi-level
/// encoder keeps one Codebook per level (P1, P2, M, P3, P4 for luminance, C, I1, I2 for
/// chromaticity) and stores in each the reconstructions its queries are compared with.
///
/// Kinds of vectors.
///   - luminance: the first channel is luminance. It is stored normalized to a discrete PDF: the
///     values divided by their L1 norm s = Σ|v| (the sum, for non-negative luminance; the paper
///     turns every luminance slice into a "conditional probability function", §4.2, and samples
///     its CDF, §5.2). The norm s is the scale of the match (c_P2, c_P3, c_P4, c_P6 of
///     equation 4): the reconstruction of the query is s × the code-vector. An all-zero
///     luminance channel is stored as the uniform PDF (1/n each) with s = 0. Further channels
///     (chromaticity of the mixed levels M, P3, P4) are stored and compared as they are.
///   - chromaticity: every channel as it is; the scale is 1.
///
/// Thresholds bound the error of the reconstruction against the query, the error the decoder
/// makes (before the scalar quantization of §4.5). Comparisons are made against normalized
/// code-vectors with the query's scale applied to them, as the paper describes ("the luminance is
/// normalized in both the inserted data-vector and the data-vector in the code-book").
///
/// Similarity measures (§4.4).
///   - mse: the mean of the squared differences over all values of the vector; a match needs
///     MSE ≤ threshold (§4.4.1; the per-level thresholds are the encoder's). Computed in
///     normalized space: MSE = (s²·Σ(q̂ − c)²_luminance + Σ(q − c)²_other) / n, q̂ = q / s, with the
///     sums of squares in float in one fixed order and combined in double.
///   - mssim: one SSIM value (equation 5) per value of the vector, each over a Gaussian window of
///     the vector's own angular neighbourhood; the dissimilarity is 1 − SSIM, and the measure is
///     its `percentile`-th percentile over all values of all channels (§4.4.2: "the
///     98th-percentile from MSSIM values for all three channels", "we allow only 2% of
///     outliers"). A match needs measure ≤ threshold. The paper leaves the following open; the
///     choices here are:
///       * the window is the WBSS04 one, a Gaussian of σ = 1.5 truncated at radius 5 (11 taps),
///         applied separably along every dimension of the vector's shape within one channel,
///         cut at the vector's borders with its weights renormalized (a slice has no data
///         beyond its ends); a window never mixes channels;
///       * C1 = (K1·L)², C2 = (K2·L)² with K1 = 0.01, K2 = 0.03 and L the dynamic range of the
///         raw (unnormalized) values, 1 by default; luminance is compared as the query against
///         s × the code-vector, i.e. SSIM of the reconstruction;
///       * the percentile is the nearest-rank one: with n values and k = ⌊(100 − p)·n / 100⌋
///         outliers allowed, the measure is the (k+1)-th largest dissimilarity (for n = 11 the
///         maximum, for n = 121 at p = 98 the third largest);
///       * early termination (§4.4.2: "prune the vector comparisons during the search as soon as
///         we achieve the percentile value already found as the current best"): a comparison
///         stops as soon as more than k values exceed the bound B = min(threshold, best so far),
///         because then its percentile exceeds B. The values are produced row by row of the
///         vector's outermost dimension (the SSIM of a row needs only the rows within the
///         window), so a hopeless candidate costs a few rows.
///
/// Search. find() returns the code-vector of least error within the threshold; among equal
/// errors the lowest index (so results are the same whatever the search order or thread count).
/// find_brute_force() computes the error of every code-vector in full and is the reference;
/// find() returns exactly the same index and error, bit for bit. Every pruning below is exact:
/// each bound carries a margin for the floating-point rounding on both sides, so nothing within
/// B is ever pruned, and the comparisons that decide are made by the same out-of-line functions
/// (the same arithmetic) as brute force.
///   - The index (both measures). Each indexed vector has a signature: its coordinates in a
///     k-dimensional principal subspace (PCA of up to 1024 of the vectors; k = index_dims) and
///     the norm of its residual outside that subspace, per channel group (luminance, other
///     channels). By Pythagoras and the triangle inequality the weighted squared distance
///     between signatures is a lower bound of that between the vectors. The signatures sit in
///     a k-d tree (median splits along the longest side of each node's bounding box, leaves of
///     8 signatures stored coordinate-major so that 8 bounds take one pass of vector
///     instructions), searched depth first, the nearer box first, pruning boxes and signatures
///     beyond the ball. Vectors added since the tree was built wait in blocks of 8 with their
///     own boxes and are scanned; the tree is rebuilt when more than max(32, 2√N) wait and the
///     subspace refitted when the code-book has grown 4×. Below 64 code-vectors every search is
///     a scan.
///   - mse: the index over the code-vectors, a range query of radius² n·threshold (then the best
///     so far), weights s² on luminance and 1 elsewhere; survivors are compared in full with
///     partial sums abandoned once above B.
///   - mssim: SSIM is not a metric, but its luminance term bounds it: SSIM = l·cs with |cs| ≤ 1,
///     so 1 − SSIM ≥ 1 − |l|, and l = (2ab + C1)/(a² + b² + C1) needs only the local means a
///     (query) and b (the scaled code-vector). (1) When every mean is non-negative (luminance;
///     not signed chromaticity, where SSIM(x, −x) is high) a value with 1 − SSIM ≤ B has
///     (a − b)² ≤ B(a² + b² + C1) and an outlier (a − b)² ≤ a² + b²; summed, every candidate
///     within B lies within a radius R(B) of the query in the space of local means
///     (search_mssim has the formula; it is tight when k = 0, as for 1-D slices of 11, and loose
///     for k > 0), so the index over the stored means answers a range query. (2) Each candidate
///     then passes the per-value test |l| ≥ 1 − B on all but k values (O(n), no windowed
///     product), (3) then the full comparison with early termination.
///   Memory per code-vector: n floats, plus a signature of Σ(k + 1) floats twice; mssim adds
///   the windowed means and variances (2n doubles).
/// Why this index: BTF slices are smooth, so a few principal components carry most of their
/// energy and the signature bound is tight; the threshold makes the search a small-radius range
/// query that the tree answers by visiting few leaves; and, unlike blocked-GEMM distances
/// (‖q‖² + ‖c‖² − 2q·c, which cancel), pruning never decides a result: brute force's own
/// arithmetic does.
///
/// Threads: find(), find_brute_force() and find_batch() may run concurrently with each other;
/// add(), find_or_add() and rebuild_index() must not run concurrently with anything.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace btf::mlvq {

/// The shape of one vector: `channels` blocks (channel-major), each of the angular `dims`,
/// outermost first (P1: {nβ}; P2: {nα, nβ}; P3: {nθv, nα, nβ}; P4: {nφv, nθv, nα, nβ}).
struct Layout {
    std::vector<uint32_t> dims;
    uint32_t channels = 1;

    /// Values per channel (the product of the dims).
    size_t channel_size() const;
    /// Values per vector.
    size_t size() const { return channel_size() * channels; }
};

enum class Kind {
    luminance,    ///< first channel normalized to unit L1 norm, with the norm as the scale
    chromaticity  ///< every channel compared as it is
};

enum class Measure {
    mse,   ///< mean squared error of the reconstruction (§4.4.1)
    mssim  ///< percentile of 1 − SSIM over every value of the vector (§4.4.2)
};

/// The SSIM parameters of Measure::mssim (defaults as in the header comment).
struct SsimOptions {
    double dynamic_range = 1.0;  ///< L of the raw values
    double k1 = 0.01;
    double k2 = 0.03;
    double sigma = 1.5;      ///< of the Gaussian window, in samples
    uint32_t radius = 5;     ///< the window's half-width in samples (5: 11 taps)
    double percentile = 98;  ///< of the dissimilarities; (0, 100]
};

struct CodebookOptions {
    std::string name = "code-book";  ///< names the code-book in error messages ("P1", "C", ...)
    Layout layout;
    Kind kind = Kind::luminance;
    Measure measure = Measure::mse;
    /// mse: the largest MSE of a match; mssim: the largest percentile of 1 − SSIM. ≥ 0; +∞
    /// makes find() a plain nearest-neighbour search.
    double threshold = 0;
    SsimOptions ssim;
    /// The index: principal coordinates per channel group in the signatures (at most the
    /// group's length). Any value gives the same results, only the speed differs: on the
    /// benchmark's slices (bench/mlvq_vq_bench.cpp) 8 was fastest for P1 × 20000 (4: 7.7× slower,
    /// 11: 5 % slower) and as fast as 4 for P2 × 5000 (16: 35 % slower).
    uint32_t index_dims = 8;
};

/// The answer to a query.
struct Match {
    static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

    uint32_t index = kNone;  ///< the code-vector; kNone when none is within the threshold
    bool added = false;      ///< find_or_add() appended the query as code-vector `index`
    /// luminance: the query's L1 norm over its first channel (the reconstruction is scale × the
    /// code-vector's first channel); chromaticity: 1.
    double scale = 1;
    /// The measure of the match (mse: the MSE; mssim: the percentile of 1 − SSIM); +∞ without a
    /// match. For a vector just added: its error against its own stored form (0 up to the
    /// rounding of the normalization).
    double error = std::numeric_limits<double>::infinity();

    explicit operator bool() const { return index != kNone; }
};

/// Counters of the work of searches (for tests and benchmarks), summed over searches: code-vectors
/// compared (their error computed, in full or until abandoned; mssim: those that passed the
/// index and the per-value test), code-vectors in the code-book, and the index's own work.
struct SearchStats {
    uint64_t searches = 0;
    uint64_t compared = 0;
    uint64_t codebook = 0;
    uint64_t bounded = 0;  ///< signatures whose lower bound the index computed
};

class Codebook {
  public:
    /// Checks the options; throws btf::Error naming the code-book and the bad option.
    explicit Codebook(CodebookOptions options);
    ~Codebook();
    Codebook(Codebook&&) noexcept;
    Codebook& operator=(Codebook&&) noexcept;
    Codebook(const Codebook&) = delete;
    Codebook& operator=(const Codebook&) = delete;

    const CodebookOptions& options() const { return m_options; }
    /// Values per vector.
    size_t length() const { return m_length; }
    /// Code-vectors.
    size_t size() const;
    /// Code-vector i as stored (luminance normalized).
    std::span<const float> vector(uint32_t i) const;

    /// Changes the threshold (training step 2 of §5.1.1 raises it 2.5×).
    void set_threshold(double threshold);

    /// The most similar code-vector within the options' threshold, or no match. Throws
    /// btf::Error if the query has the wrong length or a value that is not finite.
    Match find(std::span<const float> query) const;
    /// The same with another threshold; `stats`, if given, accumulates the work done.
    Match find(std::span<const float> query, double threshold, SearchStats* stats = nullptr) const;
    /// The reference: the error of every code-vector, in full.
    Match find_brute_force(std::span<const float> query, double threshold) const;

    /// Appends `values` as a code-vector (normalized if luminance) whatever the code-book holds;
    /// returns its index and scale. Throws btf::Error as find() does.
    Match add(std::span<const float> values);
    /// The paper's rule: find(), and add() the query when nothing is within the threshold.
    Match find_or_add(std::span<const float> query);

    /// find() for `queries.size() / length()` queries laid end to end, in parallel (oneTBB) on a
    /// code-book that does not change meanwhile (the third training step of §5.1.1: "the rest
    /// with frozen code-books"). The results are the same as one find() each, for any number of
    /// threads.
    std::vector<Match> find_batch(std::span<const float> queries) const;
    std::vector<Match> find_batch(std::span<const float> queries, double threshold) const;

    /// Refits the index to all code-vectors and rebuilds its tree with none left over to scan;
    /// worth calling once when a code-book stops growing. Results do not change.
    void rebuild_index();

    /// Reserves memory for this many code-vectors.
    void reserve(size_t code_vectors);

  private:
    struct Index;
    struct Ssim;
    struct Query;

    void prepare(std::span<const float> values, Query& q) const;
    Match search(Query& q, double threshold, bool brute_force, SearchStats* stats) const;
    Match search_mse(Query& q, double bound, bool brute_force, SearchStats* stats) const;
    Match search_mssim(Query& q, double threshold, bool brute_force, SearchStats* stats) const;
    double mse_sum(const Query& q, uint32_t i, double bound) const;
    bool mssim_rejects(const Query& q, uint32_t i, double bound) const;
    double mssim_measure(Query& q, uint32_t i, double bound) const;
    void check_threshold(double threshold) const;

    CodebookOptions m_options;
    size_t m_length = 0;
    size_t m_groups[2] = {0, 0};     ///< lengths of the channel groups (luminance, the rest)
    std::vector<float> m_data;       ///< code-vectors, stored form
    std::unique_ptr<Index> m_index;  ///< over the code-vectors (mse) or their means (mssim)
    std::unique_ptr<Ssim> m_ssim;    ///< mssim only
};

}  // namespace btf::mlvq
