#!/usr/bin/env python3
"""Checks envkit's include graph against the allowed direction.

libenv's subsystem folders and the groups each may include are read from libenv/CMakeLists.txt (its
envkit_add_group(<group> DEPS ...) calls, lowest group first), so the build and this check state one order. Checked:
  - a file in libenv/<group>/ includes only <envkit/<g>/...> or "<g>/src/..." of its own group or of a group listed
    in its DEPS, and only headers that exist;
  - libenv never includes the renderer (<envkit/render/...>), the tools, the probes or the Python module;
  - nothing outside libenv includes a libenv group's private src/ headers except the tests.
Usage: check_includes.py SOURCE_DIR [--self-test]. --self-test adds one backward include (maps -> ibl) to the graph
read from the tree and passes only if the check reports it.
"""
import os
import re
import sys

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^">]+)[">]', re.M)


def read_groups(root):
    text = open(os.path.join(root, 'libenv', 'CMakeLists.txt')).read()
    groups = {}
    for m in re.finditer(r'^envkit_add_group\(([a-z_]+)([^)]*)\)', text, re.M):
        args = m.group(2).split()
        deps = []
        if 'DEPS' in args:
            for a in args[args.index('DEPS') + 1:]:
                if a.isupper() or a.startswith('$'):
                    break
                deps.append(a)
        for d in deps:
            if d not in groups:
                raise SystemExit(f'libenv/CMakeLists.txt: group {m.group(1)} lists {d}, which is not declared before it')
        groups[m.group(1)] = set(deps)
    if not groups:
        raise SystemExit('libenv/CMakeLists.txt: no envkit_add_group() calls found')
    return groups


def source_files(root, top):
    for dirpath, _, names in os.walk(os.path.join(root, top)):
        for n in sorted(names):
            if n.endswith(('.h', '.hpp', '.cpp', '.inl')):
                yield os.path.join(dirpath, n)


def includes(path):
    return INCLUDE.findall(open(path, errors='replace').read())


def check(root, groups, extra_edges=()):
    problems = []
    libenv = os.path.join(root, 'libenv')
    for group in groups:
        allowed = groups[group] | {group}
        files = [(f, inc) for f in source_files(libenv, group) for inc in includes(f)]
        files += [(f'libenv/{group}/<self-test>', inc) for g, inc in extra_edges if g == group]
        for f, inc in files:
            rel = os.path.relpath(f, root) if os.path.isabs(f) else f
            m = re.match(r'envkit/([a-z_]+)/', inc)
            if m and m.group(1) == 'render':
                problems.append(f'{rel}: includes the renderer ({inc}); libenv never depends on renderer/')
                continue
            if m:
                target = m.group(1)
                header = os.path.join(libenv, target, 'include', inc)
            else:
                m = re.match(r'([a-z_]+)/src/', inc)
                if not m:
                    continue  # a system header, or a private header of the file's own folder
                target = m.group(1)
                header = os.path.join(libenv, inc)
            if target not in groups:
                problems.append(f'{rel}: includes {inc}, which is in no libenv group')
            elif target not in allowed:
                problems.append(f'{rel}: includes {inc}: group {group} may include only '
                                f'{", ".join(sorted(allowed))} (libenv/CMakeLists.txt)')
            elif not os.path.exists(header) and '<self-test>' not in rel:
                problems.append(f'{rel}: includes {inc}, which does not exist')
    for top in ('tools', 'renderer', 'probes', 'python'):
        for f in source_files(root, top):
            for inc in includes(f):
                if re.search(r'(^|/)libenv/[a-z_]+/src/', inc) or re.match(r'[a-z_]+/src/', inc):
                    problems.append(f'{os.path.relpath(f, root)}: includes libenv\'s private header {inc}')
    return problems


def main():
    args = [a for a in sys.argv[1:] if not a.startswith('--')]
    if len(args) != 1:
        raise SystemExit(__doc__)
    root = args[0]
    groups = read_groups(root)
    if '--self-test' in sys.argv:
        problems = check(root, groups, extra_edges=[('maps', 'envkit/ibl/prefilter.h')])
        if not any('includes envkit/ibl/prefilter.h: group maps' in p for p in problems):
            print('self-test: a backward include maps -> ibl was not reported')
            return 1
        print(f'self-test: the backward include was reported ({len(groups)} groups read)')
        return 0
    problems = check(root, groups)
    for p in problems:
        print(p)
    order = ' < '.join(groups)
    print(f'{len(problems)} problem(s); groups, lowest first: {order}')
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
