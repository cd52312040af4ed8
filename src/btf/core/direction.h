// SPDX-License-Identifier: MIT
#pragma once
/// Directions on the local hemisphere and sets of them.
///
/// Conventions (fixed once for all of btfkit; see docs/conventions.md): local frame z = surface
/// normal, x = tangent (direction of increasing u), φ measured from +x toward +y, θ from the zenith
/// in [0, π/2]. Radians inside the code; degrees on the command line, in JSON and in reports.

#include <filesystem>
#include <string>
#include <vector>

#include "btf/core/math.h"

namespace btf {

/// A direction in spherical coordinates (radians).
struct Direction {
    double theta = 0;  ///< from the zenith (surface normal)
    double phi = 0;    ///< azimuth from +x toward +y, in [0, 2π)

    /// Unit vector in the local frame.
    Vec3 vector() const;
    /// Spherical coordinates of a (not necessarily unit) vector; φ wrapped into [0, 2π).
    static Direction from_vector(const Vec3& v);
    /// From degrees, as written on the command line and in file names.
    static Direction from_degrees(double theta_deg, double phi_deg);
    double theta_deg() const { return degrees(theta); }
    double phi_deg() const { return degrees(phi); }
};

/// An ordered set of sample directions on the hemisphere (the light set or the view set of a BTF).
/// Indices into the set are what readers, codecs and the interpolator exchange.
class DirectionSet {
  public:
    DirectionSet() = default;
    DirectionSet(std::string name, std::vector<Direction> directions);

    /// The 81 directions of Bonn UBO2003 (θ rings 0, 15, 30, 45, 60, 75° with 1, 6, 12, 18, 20,
    /// 24 directions; φ from 0 evenly), in the database's index order.
    static const DirectionSet& ubo81();
    /// The 151 directions of the Bonn "UBO dome 1" sampling used by UBO2014 files.
    static const DirectionSet& dome151();
    /// Reads a text file with one direction per line, "theta_deg phi_deg" (whitespace or comma
    /// separated; '#' starts a comment). Throws btf::Error naming the file and line.
    static DirectionSet read(const std::filesystem::path& path);
    /// Writes the same text format.
    void write(const std::filesystem::path& path) const;
    /// A built-in set by name ("ubo81", "dome151") or a file path.
    static DirectionSet named(const std::string& name_or_path);

    const std::string& name() const { return m_name; }
    int size() const { return static_cast<int>(m_directions.size()); }
    bool empty() const { return m_directions.empty(); }
    const Direction& operator[](int i) const { return m_directions[i]; }
    const Vec3& vector(int i) const { return m_vectors[i]; }
    const std::vector<Direction>& directions() const { return m_directions; }
    const std::vector<Vec3>& vectors() const { return m_vectors; }

    /// Index of the direction closest (largest cosine) to `v`.
    int nearest(const Vec3& v) const;
    /// Index of a direction within `tolerance_rad` of d, or -1.
    int find(const Direction& d, double tolerance_rad = radians(0.5)) const;
    /// The subset with the given indices (in that order).
    DirectionSet subset(const std::vector<int>& indices, std::string name) const;

    /// True if both sets hold the same directions in the same order (within 1e-4 rad).
    bool same_directions(const DirectionSet& other) const;

  private:
    std::string m_name;
    std::vector<Direction> m_directions;
    std::vector<Vec3> m_vectors;
};

/// The angular sampling of a BTF: every view carries the same set of light directions.
struct Sampling {
    DirectionSet views;
    DirectionSet lights;

    int num_views() const { return views.size(); }
    int num_lights() const { return lights.size(); }
    int64_t num_images() const { return int64_t(views.size()) * lights.size(); }
};

}  // namespace btf
