// SPDX-License-Identifier: MIT
#pragma once
/// A BtfSource whose values come from a function of (view, light, texel): analytic BTFs for tests
/// and examples (a Lambertian surface under known lights, a matrix seen as a BTF, …).

#include <functional>
#include <string>
#include <utility>

#include "btf/io/source.h"

namespace btf {

class FunctionSource final : public BtfSource {
  public:
    /// Linear RGB value of texel (x, y) for view `view` and light `light`. Must be thread-safe.
    using Value = std::function<Rgb(int view, int light, int x, int y)>;

    FunctionSource(Sampling sampling, int width, int height, Value value,
                   std::string format = "function")
        : m_sampling(std::move(sampling)),
          m_width(width),
          m_height(height),
          m_value(std::move(value)) {
        m_info.format = std::move(format);
    }

    int width() const override { return m_width; }
    int height() const override { return m_height; }
    const Sampling& sampling() const override { return m_sampling; }
    const SourceInfo& info() const override { return m_info; }
    SourceInfo& info() { return m_info; }

    void read_image(int view, int light, Image& out) const override {
        out.reshape(m_width, m_height, 3);
        for (int y = 0; y < m_height; ++y)
            for (int x = 0; x < m_width; ++x) out.set_rgb(x, y, m_value(view, light, x, y));
    }
    Rgb value(int view, int light, int x, int y) const { return m_value(view, light, x, y); }

  private:
    Sampling m_sampling;
    int m_width, m_height;
    Value m_value;
    SourceInfo m_info;
};

}  // namespace btf
