// SPDX-License-Identifier: MIT
// btf manpage: the manual page btf(1), in roff, made from the help texts of the commands and
// options themselves (one source of truth: what `btf COMMAND --help` says). The build writes it
// (CMakeLists.txt: build/<preset>/man/btf.1.gz) and the Debian package installs it. Hidden from
// `btf --help`: it is for the build, not for users.

#include <fmt/format.h>

#include <cstdio>
#include <string>
#include <string_view>

#include "btf/version.h"
#include "cli.h"

namespace btf::cli {
namespace {

/// Text for roff: backslashes escaped, and `code` in bold (the help texts quote commands and
/// options in backticks).
std::string roff_text(std::string_view text) {
    std::string out;
    bool in_code = false;
    for (const char c : text) {
        if (c == '\\') {
            out += "\\e";
        } else if (c == '`') {
            out += in_code ? "\\fR" : "\\fB";
            in_code = !in_code;
        } else if (c == '-' && in_code) {
            out += "\\-";  // a minus sign in commands and options, so that they can be copied
        } else {
            out += c;
        }
    }
    if (in_code) out += "\\fR";
    return out;
}

/// A paragraph of text: lines that roff would read as requests ('.' or '\'' first) are escaped.
std::string roff_paragraph(std::string_view text) {
    std::string out = roff_text(text);
    if (!out.empty() && (out[0] == '.' || out[0] == '\'')) out.insert(0, "\\&");
    for (size_t i = out.find('\n'); i != std::string::npos; i = out.find('\n', i + 1))
        if (i + 1 < out.size() && (out[i + 1] == '.' || out[i + 1] == '\''))
            out.insert(i + 1, "\\&");
    return out;
}

/// "--components" → "\-\-components", in bold.
std::string roff_name(const std::string& name) {
    std::string out = "\\fB";
    for (const char c : name) out += c == '-' ? std::string("\\-") : std::string(1, c);
    return out + "\\fR";
}

/// One option as a tagged paragraph: its names and value type, then its help text with the
/// accepted values and the default.
std::string option_entry(const CLI::Option& option) {
    std::string names;
    if (option.get_positional()) {
        names = "\\fI" + roff_text(option.get_name(true)) + "\\fR";
    } else {
        for (const std::string& s : option.get_snames())
            names += (names.empty() ? "" : ", ") + roff_name("-" + s);
        for (const std::string& l : option.get_lnames())
            names += (names.empty() ? "" : ", ") + roff_name("--" + l);
    }
    // CLI11's type names read "INT:INT in [1 - 1048576]" or "TEXT:{f32,f16}": the value's type,
    // then what its checks accept.
    const std::string type = option.get_type_name();
    const size_t colon = type.find(':');
    const std::string value = type.substr(0, colon);
    const std::string accepted = colon == std::string::npos ? "" : type.substr(colon + 1);
    const bool flag = option.get_type_size() == 0;
    if (!flag && !value.empty() && !option.get_positional())
        names += " \\fI" + roff_text(value) + "\\fR";
    if (option.get_items_expected_max() > 1) names += " ...";

    std::string text = option.get_description();
    std::string notes;
    if (!accepted.empty()) notes = "accepts " + accepted;
    // The default, unless the help text says it in words (where 0 means "chosen for you").
    const std::string fallback = option.get_default_str();
    if (!flag && !fallback.empty() && fallback != "[]" && text.find("default") == std::string::npos)
        notes += (notes.empty() ? "" : "; ") + ("default " + fallback);
    if (option.get_required() && !option.get_positional())
        notes += (notes.empty() ? "" : "; ") + std::string("required");
    if (!notes.empty()) text += " (" + notes + ")";
    return fmt::format(".TP\n{}\n{}\n", names, roff_paragraph(text));
}

/// The visible options of `command`, positionals first or last.
std::string option_entries(const CLI::App& command, bool positional) {
    std::string out;
    for (const CLI::Option* option : command.get_options()) {
        if (option->get_group().empty() || option->get_positional() != positional) continue;
        if (option->get_lnames().size() == 1 && option->get_lnames()[0] == "help") continue;
        out += option_entry(*option);
    }
    return out;
}

/// A command and its own subcommands: its synopsis, description, arguments and options.
std::string command_section(const CLI::App& command, const std::string& path) {
    std::string usage = "\\fB" + roff_text(path) + "\\fR";
    bool has_options = false;
    for (const CLI::Option* option : command.get_options()) {
        if (option->get_group().empty() || option->get_positional()) continue;
        if (!(option->get_lnames().size() == 1 && option->get_lnames()[0] == "help"))
            has_options = true;
    }
    if (has_options) usage += " [\\fIOPTIONS\\fR]";
    for (const CLI::Option* option : command.get_options()) {
        if (!option->get_positional() || option->get_group().empty()) continue;
        std::string name = "\\fI" + roff_text(option->get_name(true)) + "\\fR";
        if (option->get_items_expected_max() > 1) name += " ...";
        usage += option->get_required() ? " " + name : " [" + name + "]";
    }
    const auto subcommands =
        command.get_subcommands([](const CLI::App* sub) { return !sub->get_group().empty(); });
    if (!subcommands.empty()) usage += " \\fICOMMAND\\fR";

    std::string out =
        fmt::format(".SS \"{}\"\n{}\n", usage, roff_paragraph(command.get_description()));
    const std::string positionals = option_entries(command, true);
    const std::string options = option_entries(command, false);
    if (!positionals.empty()) out += ".PP\nArguments:\n.RS\n" + positionals + ".RE\n";
    if (!options.empty()) out += ".PP\nOptions:\n.RS\n" + options + ".RE\n";
    if (!command.get_footer().empty()) out += ".PP\n" + roff_paragraph(command.get_footer()) + "\n";
    for (const CLI::App* sub : subcommands)
        out += command_section(*sub, path + " " + sub->get_name());
    return out;
}

std::string manual_page(const CLI::App& app) {
    std::string page = fmt::format(
        ".\\\" Made by `btf manpage` from the help texts of btfkit {}'s commands.\n"
        ".TH BTF 1 \"\" \"btfkit {}\" \"User Commands\"\n",
        version(), version());
    // The description reads "btf: what it does"; NAME wants "btf \- what it does".
    std::string summary = app.get_description();
    if (summary.rfind("btf: ", 0) == 0) summary.erase(0, 5);
    page += ".SH NAME\nbtf \\- " + roff_text(summary) + "\n";
    page +=
        ".SH SYNOPSIS\n\\fBbtf\\fR [\\fIGLOBAL OPTIONS\\fR] \\fICOMMAND\\fR [\\fIOPTIONS\\fR] "
        "[\\fIARGUMENTS\\fR]\n";
    page += ".SH DESCRIPTION\n" +
            roff_paragraph("`btf` is btfkit's command: " + summary +
                           ". Each command below says what it reads and writes; `btf COMMAND "
                           "--help` prints the same text.") +
            "\n";
    page += ".SH GLOBAL OPTIONS\nBefore the command name.\n" + option_entries(app, false);
    page += ".SH COMMANDS\n";
    for (const CLI::App* command :
         app.get_subcommands([](const CLI::App* sub) { return !sub->get_group().empty(); }))
        page += command_section(*command, "btf " + command->get_name());
    // What main() returns (tools/btf/main.cpp).
    page +=
        ".SH EXIT STATUS\n"
        ".TP\n0\nSuccess.\n"
        ".TP\n1\nAn error: one line on standard error names the file and the problem; no partial "
        "output is left.\n"
        ".TP\n2\nAn internal error.\n"
        ".TP\n100\\(en115\nArguments that do not parse (a missing or unknown option, a value out "
        "of range: CLI11's exit codes); the message says which.\n"
        ".TP\n130\nCancelled (Ctrl\\-C); temporary files are removed.\n";
    page += ".SH SEE ALSO\n\\fBmpirun\\fR(1); the documentation in /usr/share/doc/btfkit.\n";
    return page;
}

}  // namespace

Command register_manpage(CLI::App& app, GlobalOptions&) {
    CLI::App* cmd = app.add_subcommand("manpage", "Print the manual page btf(1), in roff");
    cmd->group("");  // hidden
    return {cmd, [&app] { std::fputs(manual_page(app).c_str(), stdout); }};
}

}  // namespace btf::cli
