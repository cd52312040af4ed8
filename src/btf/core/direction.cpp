// SPDX-License-Identifier: MIT
#include "btf/core/direction.h"

#include <charconv>
#include <fstream>
#include <sstream>

#include "btf/util/atomic_file.h"
#include "btf/util/error.h"

namespace btf {

Vec3 Direction::vector() const {
    const double s = std::sin(theta);
    return {s * std::cos(phi), s * std::sin(phi), std::cos(theta)};
}

Direction Direction::from_vector(const Vec3& v) {
    const double len = length(v);
    if (!(len > 0)) return {};
    const double z = std::clamp(v.z / len, -1.0, 1.0);
    double phi = std::atan2(v.y, v.x);
    if (phi < 0) phi += 2 * kPi;
    if (phi >= 2 * kPi) phi -= 2 * kPi;
    return {std::acos(z), phi};
}

Direction Direction::from_degrees(double theta_deg, double phi_deg) {
    double phi = std::fmod(phi_deg, 360.0);
    if (phi < 0) phi += 360.0;
    return {radians(theta_deg), radians(phi)};
}

DirectionSet::DirectionSet(std::string name, std::vector<Direction> directions)
    : m_name(std::move(name)), m_directions(std::move(directions)) {
    m_vectors.reserve(m_directions.size());
    for (const Direction& d : m_directions) m_vectors.push_back(d.vector());
}

namespace {

DirectionSet make_rings(std::string name, const std::vector<double>& thetas,
                        const std::vector<int>& counts, const std::vector<double>& offsets) {
    std::vector<Direction> dirs;
    for (size_t r = 0; r < thetas.size(); ++r)
        for (int i = 0; i < counts[r]; ++i)
            dirs.push_back(Direction::from_degrees(thetas[r], offsets[r] + 360.0 * i / counts[r]));
    return DirectionSet(std::move(name), std::move(dirs));
}

}  // namespace

const DirectionSet& DirectionSet::ubo81() {
    static const DirectionSet set =
        make_rings("ubo81", {0, 15, 30, 45, 60, 75}, {1, 6, 12, 18, 20, 24}, {0, 0, 0, 0, 0, 0});
    return set;
}

const DirectionSet& DirectionSet::dome151() {
    static const DirectionSet set =
        make_rings("dome151", {0, 11, 23.5, 30, 37.5, 45, 52.5, 60, 67.5, 75},
                   {1, 6, 12, 12, 12, 18, 18, 24, 24, 24}, {0, 15, 0, 15, 0, 0, 7.5, 0, 7.5, 0});
    return set;
}

DirectionSet DirectionSet::read(const std::filesystem::path& path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        fail("{}: no such direction-set file (built-in sets: ubo81, dome151)", path.string());
    std::ifstream in(path);
    if (!in) fail("{}: cannot open direction set", path.string());
    std::vector<Direction> dirs;
    std::string line;
    int line_no = 0;
    while (std::getline(in, line)) {
        ++line_no;
        if (auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
        for (char& c : line)
            if (c == ',' || c == '\t' || c == ';') c = ' ';
        std::istringstream fields(line);
        std::string a, b, extra;
        if (!(fields >> a)) continue;
        if (!(fields >> b) || (fields >> extra))
            fail("{}: line {}: expected two numbers 'theta_deg phi_deg'", path.string(), line_no);
        double theta = 0, phi = 0;
        auto parse = [&](const std::string& s, double& out) {
            auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
            if (ec != std::errc() || ptr != s.data() + s.size() || !std::isfinite(out))
                fail("{}: line {}: '{}' is not a number", path.string(), line_no, s);
        };
        parse(a, theta);
        parse(b, phi);
        if (theta < 0 || theta > 90)
            fail("{}: line {}: theta {} is outside [0, 90] degrees", path.string(), line_no, theta);
        dirs.push_back(Direction::from_degrees(theta, phi));
    }
    if (dirs.empty()) fail("{}: no directions in file", path.string());
    return DirectionSet(path.stem().string(), std::move(dirs));
}

void DirectionSet::write(const std::filesystem::path& path) const {
    AtomicOutput out(path);
    {
        std::ofstream f(out.temp_path());
        f << "# btfkit direction set '" << m_name << "': theta_deg phi_deg\n";
        for (const Direction& d : m_directions)
            f << fmt::format("{:.6f} {:.6f}\n", d.theta_deg(), d.phi_deg());
        if (!f) fail("{}: write failed", path.string());
    }
    out.commit();
}

DirectionSet DirectionSet::named(const std::string& name_or_path) {
    if (name_or_path == "ubo81") return ubo81();
    if (name_or_path == "dome151") return dome151();
    return read(name_or_path);
}

int DirectionSet::nearest(const Vec3& v) const {
    int best = -1;
    double best_cos = -2;
    for (int i = 0; i < size(); ++i) {
        const double c = dot(m_vectors[i], v);
        if (c > best_cos) best_cos = c, best = i;
    }
    return best;
}

int DirectionSet::find(const Direction& d, double tolerance_rad) const {
    const Vec3 v = d.vector();
    const int i = nearest(v);
    if (i < 0) return -1;
    return dot(m_vectors[i], v) >= std::cos(tolerance_rad) ? i : -1;
}

DirectionSet DirectionSet::subset(const std::vector<int>& indices, std::string name) const {
    std::vector<Direction> dirs;
    dirs.reserve(indices.size());
    for (int i : indices) dirs.push_back(m_directions.at(i));
    return DirectionSet(std::move(name), std::move(dirs));
}

bool DirectionSet::same_directions(const DirectionSet& other) const {
    if (size() != other.size()) return false;
    for (int i = 0; i < size(); ++i)
        if (dot(m_vectors[i], other.m_vectors[i]) < std::cos(1e-4)) return false;
    return true;
}

}  // namespace btf
