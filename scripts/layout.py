#!/usr/bin/env python3
"""Checks the layout rules of ARCHITECTURE.md on the source tree (no dependencies):

1. no cycle among the library's modules: a module's code (comments left out) names
   `crate::…` or `super::…` paths; each names the deepest module it reaches, and a module
   "uses" that module unless one contains the other (a parent declares its children, a
   child reads its parent's items); the strongly connected components of that graph must
   all be single modules;
2. no file-extension dispatch outside `src/io/`: no `.extension()`, no
   `eq_ignore_ascii_case("…")`, no `ends_with(".…")` / `strip_suffix(".…")` in the code of
   the library, the command line or the Python bindings;
3. no error told apart by its text in the front ends (`cli/src`, `python/`): no
   `.contains(…)` on a message (`e`, `err`, `msg`, `message`, `…to_string()`), no
   `in str(e)` in Python.

Usage: python3 scripts/layout.py [--graph]   (exit status 1 when a rule is broken)
"""

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"


def strip_comments(code):
    """The code without comments and string literals' contents (kept as "")."""
    out, i, n = [], 0, len(code)
    while i < n:
        if code.startswith("//", i):
            j = code.find("\n", i)
            i = n if j < 0 else j
        elif code.startswith("/*", i):
            j = code.find("*/", i + 2)
            i = n if j < 0 else j + 2
        elif code[i] == '"' and not (i > 0 and code[i - 1] == "'"):
            j = i + 1
            while j < n and code[j] != '"':
                j += 2 if code[j] == "\\" else 1
            out.append('""')
            i = j + 1
        elif code.startswith("r#\"", i):
            j = code.find('"#', i + 3)
            out.append('""')
            i = n if j < 0 else j + 2
        else:
            out.append(code[i])
            i += 1
    return "".join(out)


def module_of(path):
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("mod", "lib"):
        parts.pop()
    return tuple(parts)


def test_only(path):
    return path.name == "tests.rs"


def modules():
    """module path -> code (test modules left out: they may reach anything)."""
    mods = {}
    for p in sorted(SRC.rglob("*.rs")):
        if test_only(p):
            continue
        code = strip_comments(p.read_text())
        # `#[cfg(test)] mod tests { … }` at the end of a file.
        m = re.search(r"#\[cfg\(test\)\]\s*mod tests\s*\{", code)
        if m:
            code = code[: m.start()]
        mods[module_of(p)] = code
    return mods


PATH = re.compile(r"(?<![\w:])((?:crate|super|self)(?:::(?:super|[A-Za-z_]\w*))*)")
GROUP = re.compile(r"(?<![\w:])((?:crate|super|self)(?:::(?:super|[a-z_]\w*))*)::\{([^;]*?)\}\s*;", re.S)


def targets(mod, code, known):
    """The modules `mod` names."""
    names = []
    for m in GROUP.finditer(code):
        base = m.group(1)
        for item in re.split(r",(?![^{]*\})", m.group(2)):
            first = re.match(r"\s*([a-z_]\w*)", item)
            if first:
                names.append(base + "::" + first.group(1))
    names += [m.group(1) for m in PATH.finditer(code)]
    out = set()
    for name in names:
        segs = name.split("::")
        cur = list(mod)
        if segs[0] == "crate":
            cur, segs = [], segs[1:]
        elif segs[0] == "self":
            segs = segs[1:]
        while segs and segs[0] == "super":
            cur = cur[:-1]
            segs = segs[1:]
        path = tuple(cur)
        for s in segs:
            if path + (s,) in known:
                path = path + (s,)
            else:
                break
        out.add(path)
    return out


def related(a, b):
    return a[: len(b)] == b or b[: len(a)] == a


def cycles(graph):
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return comps


def name(m):
    return "::".join(m) or "crate"


def check_cycles(show_graph):
    mods = modules()
    known = set(mods)
    graph = {m: {t for t in targets(m, c, known) if t in known and not related(m, t)}
             for m, c in mods.items()}
    if show_graph:
        for m in sorted(graph):
            print(f"{name(m)} -> {', '.join(name(t) for t in sorted(graph[m]))}")
    comps = cycles(graph)
    for comp in comps:
        print("cycle: " + " <-> ".join(name(m) for m in comp))
        for a in comp:
            for b in comp:
                if b in graph[a]:
                    print(f"  {name(a)} uses {name(b)}")
    edges = sum(len(v) for v in graph.values())
    print(f"modules: {len(graph)}, uses between them: {edges}, cycles: {len(comps)}")
    return not comps


def code_files(*dirs, exts=(".rs",)):
    for d in dirs:
        for p in sorted((ROOT / d).rglob("*")):
            if p.suffix in exts and "tests" not in p.relative_to(ROOT).parts:
                yield p


DISPATCH = re.compile(
    r"\.extension\(\)|eq_ignore_ascii_case\(\"|ends_with\(\"\.|strip_suffix\(\"\.")
TEXT_MATCH = re.compile(
    r"\b(?:e|err|error|msg|message)\.contains\(|to_string\(\)\.contains\(")


def check_grep():
    ok = True
    for p in code_files("src", "cli/src", "python/src"):
        rel = p.relative_to(ROOT)
        if rel.parts[:2] == ("src", "io"):
            continue
        lines = p.read_text().splitlines()
        # A file's unit tests (`#[cfg(test)] mod tests`, at its end) may do anything.
        end = next((i for i, l in enumerate(lines)
                    if l.startswith("#[cfg(test)]") and i + 1 < len(lines)
                    and lines[i + 1].startswith("mod tests")), len(lines))
        for no, line in enumerate(lines[:end], 1):
            head = line.split("//")[0]
            if DISPATCH.search(head):
                print(f"extension dispatch outside src/io: {rel}:{no}: {line.strip()}")
                ok = False
            if rel.parts[0] in ("cli", "python") and TEXT_MATCH.search(head):
                print(f"error told apart by its text: {rel}:{no}: {line.strip()}")
                ok = False
    for p in code_files("python/sparse_levelset", exts=(".py",)):
        for no, line in enumerate(p.read_text().splitlines(), 1):
            if re.search(r"\bin str\((?:e|err|exc|error)\)", line):
                print(f"error told apart by its text: {p.relative_to(ROOT)}:{no}: {line.strip()}")
                ok = False
    print("extension dispatch outside src/io and error-text matching: "
          + ("none" if ok else "found"))
    return ok


if __name__ == "__main__":
    good = check_cycles("--graph" in sys.argv)
    good = check_grep() and good
    sys.exit(0 if good else 1)
