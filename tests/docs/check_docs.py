#!/usr/bin/env python3
"""Checks that the user-facing docs name only things that exist.

README.md, BENCHMARKS.md and docs/*.md are read; for each of them:
  - every repository path they name (libenv/..., tools/..., docs/...) exists in the source tree;
  - every env* tool run in a command line is a built tool (or `python3 -m envkit.batch` / `envkit.farm`);
  - every --flag given to a tool in a command line is one its --help lists.
Command lines are the lines of fenced code blocks (```sh or unlabelled) and the inline code spans that run a tool
(`envbake --tables hierarchical,sun`, `time build/bin/envconvert --help`). Each mismatch is printed as
"<doc>:<line>: <what> does not exist"; the exit status is 1 if there is any.

Usage: check_docs.py SOURCE_DIR BIN_DIR [PYTHON_DIR]
       check_docs.py --self-test SOURCE_DIR BIN_DIR [PYTHON_DIR]   (the checker flags a made-up flag and path)
"""

import glob
import os
import re
import shlex
import subprocess
import sys
import tempfile

TOOLS = ("envconvert", "envinfo", "envdiff", "envbake", "envsample", "envprefilter", "envmerge", "envprobe",
         "envrender", "envproduct")
PYTHON_MODULES = ("envkit.batch", "envkit.farm")

# Top-level directories of the repository; a word starting with one of them and a slash is a path.
TOP_DIRS = ("libenv", "renderer", "tools", "scripts", "tests", "docs", "python", "web", "probes")
# The look-behind leaves out what is not in the source tree: outputs (build/python/..., out/docs/...), absolute
# paths, URLs, and <commit>:<path> (checked by REV_PATH_RE).
PATH_RE = re.compile(r"(?<![A-Za-z0-9_.:/-])(?:\./)?((?:%s)/[A-Za-z0-9_./{},*%%<>-]*[A-Za-z0-9_}*>])"
                     % "|".join(TOP_DIRS))
# A path written as <commit>:<path> (git show's form) names a file of that commit, not of the tree.
REV_PATH_RE = re.compile(r"\b([0-9a-f]{7,40}\^*(?:~\d+)?):((?:%s)/[A-Za-z0-9_./-]*[A-Za-z0-9])"
                         % "|".join(TOP_DIRS))

TOOL_TOKEN_RE = re.compile(r"^(?:\S*/)?(env[a-z]+)$")
FLAG_RE = re.compile(r"^--[A-Za-z0-9][A-Za-z0-9-]*")
# Words that run the command after them (and their own options, which are not the tool's).
WRAPPERS = {"time", "sudo", "nice", "exec", "command", "env", "do", "then", "else"}
COMMAND_SEPARATORS_RE = re.compile(r"\|\||&&|[|;]|\$\(|`")


def fenced_and_prose(lines):
    """Splits a markdown file into command lines of fenced shell blocks and prose lines.

    Returns (commands, prose): commands is a list of (line number, text) with backslash continuations joined,
    prose the file's lines with every fenced line blanked (so inline code spans keep their line numbers)."""
    commands, prose = [], []
    fence, shell, pending, pending_line = None, False, "", 0
    for number, line in enumerate(lines, 1):
        stripped = line.strip()
        if fence is None and stripped.startswith("```"):
            fence, shell = "```", stripped[3:].strip() in ("", "sh", "bash", "shell", "console")
            prose.append("")
            continue
        if fence is not None:
            prose.append("")
            if stripped.startswith(fence):
                fence = None
                continue
            if not shell:
                continue
            if not pending:
                pending_line = number
            if line.rstrip().endswith("\\"):
                pending += line.rstrip()[:-1] + " "
                continue
            commands.append((pending_line, pending + line))
            pending = ""
            continue
        prose.append(line)
    return commands, prose


def inline_spans(prose):
    """(line number, text) of each inline code span of the prose; a span may wrap onto the next lines."""
    text = "\n".join(prose)
    for match in re.finditer(r"(`+)(.+?)\1", text, re.S):
        if "\n\n" in match.group(2):
            continue
        yield text.count("\n", 0, match.start()) + 1, match.group(2).replace("\n", " ")


def split_words(segment):
    try:
        return shlex.split(segment, comments=True)
    except ValueError:  # an unbalanced quote in a shortened example: whitespace is close enough
        return segment.split()


def command_segments(command):
    """The simple commands of a shell line: split at pipes, ;, &&, || and command substitutions."""
    return [s for s in COMMAND_SEPARATORS_RE.split(command) if s.strip()]


def find_tool(words):
    """(index, name) of the tool a command runs, or None.

    The tool is the first word after variable assignments and wrappers (time, sudo...), or a built tool anywhere
    later (valgrind ... build/bin/envrender); `python3 -m envkit.batch` names the module."""
    position = 0
    while position < len(words) and (re.match(r"^\w+=", words[position]) or words[position] in WRAPPERS):
        position += 1
    for index in range(position, len(words)):
        word = words[index]
        if index + 2 <= len(words) - 1 and re.search(r"(^|/)python3?$", word) and words[index + 1] == "-m":
            module = words[index + 2]
            if module.startswith("envkit"):
                return index + 2, module
        match = TOOL_TOKEN_RE.match(word)
        if match and (index == position or match.group(1) in TOOLS):
            return index, match.group(1)
    return None


class Checker:
    def __init__(self, source_dir, bin_dir, python_dir):
        self.source_dir = source_dir
        self.bin_dir = bin_dir
        self.python_dir = python_dir
        self.help_cache = {}
        self.problems = []
        self.counts = {"paths": 0, "commands": 0, "options": 0}
        self.unchecked_modules = set()

    # --- what exists -------------------------------------------------------------------------------------------
    def help_text(self, command):
        key = tuple(command)
        if key not in self.help_cache:
            env = dict(os.environ)
            if self.python_dir:
                env["PYTHONPATH"] = self.python_dir
            try:
                result = subprocess.run(command, capture_output=True, text=True, timeout=60, env=env)
                self.help_cache[key] = result.stdout + result.stderr if result.returncode == 0 else None
            except OSError:
                self.help_cache[key] = None
        return self.help_cache[key]

    def module_built(self):
        return self.python_dir is not None and os.path.exists(os.path.join(self.python_dir, "envkit", "__init__.py"))

    def tool_command(self, tool):
        if tool in PYTHON_MODULES:
            return [sys.executable, "-m", tool]
        path = os.path.join(self.bin_dir, tool)
        return [path] if tool in TOOLS and os.access(path, os.X_OK) else None

    @staticmethod
    def listed_flags(help_text):
        """The long options of a --help text: the first column of its option lines (CLI11 and argparse)."""
        flags = set()
        for line in help_text.splitlines():
            match = re.match(r"^\s+(-\S.*?)(?:\s{2,}|$)", line)
            if match:
                flags.update(re.findall(r"--[A-Za-z0-9][A-Za-z0-9-]*", match.group(1)))
        return flags

    @staticmethod
    def subcommands(help_text):
        """Subcommand names of a CLI11 --help ("Subcommands:" section), empty when the tool has none."""
        names, inside = set(), False
        for line in help_text.splitlines():
            if re.match(r"^Subcommands?:", line):
                inside = True
            elif inside and re.match(r"^\s+(\w[\w-]*)", line):
                names.add(line.split()[0])
            elif inside and line.strip() and not line.startswith(" "):
                inside = False
        return names

    def accepted_flags(self, tool, words_after_tool):
        base = self.tool_command(tool)
        top = self.help_text(base + ["--help"])
        if top is None:
            return None
        flags = self.listed_flags(top)
        subs = self.subcommands(top)
        sub = next((w for w in words_after_tool if not w.startswith("-")), None)
        if sub in subs:
            sub_help = self.help_text(base + [sub, "--help"])
            if sub_help is not None:
                flags |= self.listed_flags(sub_help)
        return flags

    # --- checks --------------------------------------------------------------------------------------------------
    def report(self, doc, line, what):
        self.problems.append("%s:%d: %s does not exist" % (doc, line, what))

    def check_command(self, doc, line, command, from_span):
        for segment in command_segments(command):
            words = split_words(segment)
            found = find_tool(words)
            if found is None:
                continue
            index, tool = found
            if from_span and tool not in TOOLS and tool not in PYTHON_MODULES and not any(
                    w.startswith("-") for w in words):
                continue  # words in code font without an option (`envkit openexr gl`) are names, not a command
            if tool not in TOOLS and tool not in PYTHON_MODULES:
                self.report(doc, line, "tool '%s'" % tool)
                continue
            if self.tool_command(tool) is None:
                self.report(doc, line, "tool '%s' (not built in %s)" % (tool, self.bin_dir))
                continue
            if tool in PYTHON_MODULES and not self.module_built():
                self.unchecked_modules.add(tool)  # a build without the Python module cannot say what it accepts
                continue
            self.counts["commands"] += 1
            rest = words[index + 1:]
            flags = self.accepted_flags(tool, rest)
            if flags is None:
                self.report(doc, line, "'%s --help'" % tool)
                continue
            for word in rest:
                match = FLAG_RE.match(word)
                if match:
                    self.counts["options"] += 1
                if match and match.group(0) not in flags:
                    self.report(doc, line, "option '%s' of %s" % (match.group(0), tool))

    def path_exists(self, path):
        if "<" in path or "%" in path:
            return True  # a placeholder (<name>) or a cube-face pattern (sky_%.png): not a file name
        for expanded in expand_braces(path):
            full = os.path.join(self.source_dir, expanded.rstrip("/"))
            if "*" in expanded:
                if not glob.glob(full):
                    return False
            elif not os.path.exists(full):
                return False
        return True

    def check_paths(self, doc, lines):
        in_git = os.path.exists(os.path.join(self.source_dir, ".git"))  # a source tarball cannot say
        for number, line in enumerate(lines, 1):
            for match in REV_PATH_RE.finditer(line):
                revision_path = "%s:%s" % match.groups()
                if in_git and subprocess.run(["git", "-C", self.source_dir, "cat-file", "-e", revision_path],
                                             capture_output=True).returncode != 0:
                    self.report(doc, number, "'%s'" % revision_path)
            for match in PATH_RE.finditer(line):
                path = match.group(1)
                self.counts["paths"] += 1
                if not self.path_exists(path):
                    self.report(doc, number, "path '%s'" % path)

    def check_doc(self, path, shown_name):
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
        self.check_paths(shown_name, lines)
        commands, prose = fenced_and_prose(lines)
        for number, command in commands:
            self.check_command(shown_name, number, command, from_span=False)
        for number, span in inline_spans(prose):
            self.check_command(shown_name, number, span, from_span=True)


def expand_braces(path):
    """sphere_{a,b}.json -> sphere_a.json, sphere_b.json (nested braces too)."""
    match = re.search(r"\{([^{}]*)\}", path)
    if not match:
        return [path]
    out = []
    for option in match.group(1).split(","):
        out += expand_braces(path[:match.start()] + option + path[match.end():])
    return out


def docs_of(source_dir):
    names = ["README.md", "BENCHMARKS.md"] + sorted(
        os.path.relpath(p, source_dir) for p in glob.glob(os.path.join(source_dir, "docs", "*.md")))
    return [n for n in names if os.path.exists(os.path.join(source_dir, n))]


def self_test(source_dir, bin_dir, python_dir):
    """The checker must flag a made-up option, tool and path, and pass their real counterparts."""
    doc = "\n".join([
        "Convert with `envconvert sky.exr -o c.exr --to cube --no-such-flag`.",  # line 1: bad flag
        "```sh",
        "envconvert sky.exr -o c.exr --to cube --size 512   # fine",
        "envfrobnicate sky.exr",  # line 4: bad tool
        "```",
        "See tools/no_such_tool.cpp and tools/envconvert.cpp.",  # line 6: bad path
        "Or `python3 -m envkit.batch in/ out/ --workers 2 --no-such-option`.",  # line 7: bad module option
        "Scenes scripts/report/scenes/sphere_{diffuse,glossy}_sunny.json, scripts/report/scenes/{default,no}.json",  # 8
        "Removed: c779d0e^:renderer/src/product_sampling.cpp, c779d0e^:tools/no_such_tool.cpp",  # line 9
        "",
    ])
    expected = {
        "SELFTEST.md:1: option '--no-such-flag' of envconvert does not exist",
        "SELFTEST.md:4: tool 'envfrobnicate' does not exist",
        "SELFTEST.md:6: path 'tools/no_such_tool.cpp' does not exist",
        "SELFTEST.md:8: path 'scripts/report/scenes/{default,no}.json' does not exist",
    }
    checker = Checker(source_dir, bin_dir, python_dir)
    if os.path.exists(os.path.join(source_dir, ".git")):  # as check_paths
        expected.add("SELFTEST.md:9: 'c779d0e^:tools/no_such_tool.cpp' does not exist")
    if checker.module_built():
        expected.add("SELFTEST.md:7: option '--no-such-option' of envkit.batch does not exist")
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "SELFTEST.md")
        with open(path, "w", encoding="utf-8") as f:
            f.write(doc)
        checker.check_doc(path, "SELFTEST.md")
    found = set(checker.problems)
    if found != expected:
        print("self-test failed:\n  expected: %s\n  found:    %s" % (sorted(expected), sorted(found)))
        return 1
    print("self-test passed: %d made-up names flagged, real ones accepted" % len(expected))
    return 0


def main(argv):
    selftest = "--self-test" in argv
    args = [a for a in argv if a != "--self-test"]
    if len(args) not in (2, 3):
        print(__doc__.strip().splitlines()[-2].strip(), file=sys.stderr)
        return 2
    source_dir, bin_dir = os.path.abspath(args[0]), os.path.abspath(args[1])
    python_dir = os.path.abspath(args[2]) if len(args) == 3 else None
    if selftest:
        return self_test(source_dir, bin_dir, python_dir)
    checker = Checker(source_dir, bin_dir, python_dir)
    docs = docs_of(source_dir)
    for name in docs:
        checker.check_doc(os.path.join(source_dir, name), name)
    for problem in checker.problems:
        print(problem)
    print("%d docs checked (%d paths, %d tool command lines, %d options): %d mismatches" % (
        len(docs), checker.counts["paths"], checker.counts["commands"], checker.counts["options"],
        len(checker.problems)))
    if checker.unchecked_modules:
        print("not checked: the options of %s (the Python module is not built in %s)" % (
            ", ".join(sorted(checker.unchecked_modules)), python_dir))
    return 1 if checker.problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
