// SPDX-License-Identifier: MIT
#pragma once
// Reads an XML document (an SVG, or a polyglot HTML page) into a flat element list with expat, so
// tests can check what btfkit writes by its structure (GoogleTest only; not part of the library;
// tests that include it are linked with expat).

#include <expat.h>

#include <map>
#include <string>
#include <vector>

namespace btf::test {

struct XmlElement {
    std::string name;
    std::map<std::string, std::string> attributes;
    std::string text;  ///< all character data inside, descendants' included
    int parent = -1;
    std::vector<int> children;

    std::string attribute(const std::string& key) const {
        const auto it = attributes.find(key);
        return it == attributes.end() ? std::string() : it->second;
    }
};

struct XmlDocument {
    std::vector<XmlElement> elements;  ///< in document order; elements[0] is the root
    std::string error;                 ///< expat's message and line when not well-formed

    bool ok() const { return error.empty() && !elements.empty(); }

    /// Indices of the elements named `name` (inside `within` when it is >= 0), in document order.
    std::vector<int> find(const std::string& name, int within = -1) const {
        std::vector<int> out;
        for (int i = 0; i < int(elements.size()); ++i) {
            if (elements[size_t(i)].name != name) continue;
            if (within >= 0 && !inside(i, within)) continue;
            out.push_back(i);
        }
        return out;
    }
    /// The first element named `name` whose attribute `key` equals `value`, or -1.
    int find_with(const std::string& name, const std::string& key, const std::string& value) const {
        for (int i : find(name))
            if (elements[size_t(i)].attribute(key) == value) return i;
        return -1;
    }
    bool inside(int element, int ancestor) const {
        for (int p = elements[size_t(element)].parent; p >= 0; p = elements[size_t(p)].parent)
            if (p == ancestor) return true;
        return false;
    }
    const XmlElement& operator[](int i) const { return elements[size_t(i)]; }
};

inline XmlDocument parse_xml(const std::string& text) {
    struct State {
        XmlDocument doc;
        std::vector<int> open;
    } state;
    XML_Parser parser = XML_ParserCreate("UTF-8");
    XML_SetUserData(parser, &state);
    XML_SetElementHandler(
        parser,
        [](void* data, const XML_Char* name, const XML_Char** attributes) {
            State& s = *static_cast<State*>(data);
            XmlElement element;
            element.name = name;
            for (int i = 0; attributes[i]; i += 2)
                element.attributes[attributes[i]] = attributes[i + 1];
            element.parent = s.open.empty() ? -1 : s.open.back();
            const int index = int(s.doc.elements.size());
            if (element.parent >= 0)
                s.doc.elements[size_t(element.parent)].children.push_back(index);
            s.doc.elements.push_back(std::move(element));
            s.open.push_back(index);
        },
        [](void* data, const XML_Char*) { static_cast<State*>(data)->open.pop_back(); });
    XML_SetCharacterDataHandler(parser, [](void* data, const XML_Char* chars, int length) {
        State& s = *static_cast<State*>(data);
        for (const int i : s.open) s.doc.elements[size_t(i)].text.append(chars, size_t(length));
    });
    if (XML_Parse(parser, text.data(), int(text.size()), 1) == XML_STATUS_ERROR) {
        state.doc.error = std::string(XML_ErrorString(XML_GetErrorCode(parser))) + " at line " +
                          std::to_string(XML_GetCurrentLineNumber(parser));
    }
    XML_ParserFree(parser);
    return state.doc;
}

}  // namespace btf::test
