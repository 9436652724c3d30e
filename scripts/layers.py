#!/usr/bin/env python3
"""The library's layering, checked (run by scripts/test.sh):

1. Lean: `cargo tree -p nmci -e normal` with default features holds none of the CLI's
   dependencies (clap, indicatif, toml) nor the plotting library (feature `charts`).
2. One-way: the modules of src/ (one per file) import each other without a loop. An edge
   A -> B is any path into B written in A (`use crate::b::…`, `super::b::…`, `crate::b::f(…)`);
   a parent's `pub use` of its own children is its facade, not a dependency, and a name
   taken through a facade is an edge to where it is defined. Unit tests (`#[cfg(test)] mod`)
   are left out: a test may drive the layers above its module. A loop is printed with the
   lines that make each edge.
3. Short: no function of the library's code (src/, cli/src/, python/src/, shims/*/src/) is
   longer than MAX_FN_LINES lines, from `fn` to its closing brace: a proof step a reviewer
   checks fits on a screen or two (docs/development.md, "Functions").

`python3 scripts/layers.py --graph` prints the module graph instead; `--functions` the ten
longest functions.
"""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
FORBIDDEN = ["clap", "indicatif", "toml", "plotters"]
MAX_FN_LINES = 150
CODE = ["src", "cli/src", "python/src", "shims/blas/src", "shims/lapack/src"]


def lean() -> list[str]:
    out = subprocess.run(
        ["cargo", "tree", "-p", "nmci", "-e", "normal", "--prefix", "none"],
        cwd=ROOT, check=True, capture_output=True, text=True,
    ).stdout
    crates = {line.split()[0] for line in out.splitlines() if line.strip()}
    return [f"the library depends on {c} (a CLI or plotting dependency)" for c in FORBIDDEN if c in crates]


def module_of(path: Path) -> tuple[str, ...]:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] in ("mod", "lib"):
        parts.pop()
    return tuple(parts)


def strip_comments(text: str) -> str:
    """The code without comments and without its unit tests (`#[cfg(test)] mod …` to the end
    of the file: a test may drive the layers above its module)."""
    text = re.split(r"#\[cfg\(test\)\]\s*(?:#\[[^\]]*\]\s*)*mod\s", text)[0]
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return "\n".join(re.sub(r"//.*", "", line) for line in text.splitlines())


def use_trees(text: str):
    """(line number, full path) of every path in a `use` declaration, nested braces expanded."""
    for m in re.finditer(r"(?:pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", text):
        line = text.count("\n", 0, m.start()) + 1
        reexport = m.group(0).startswith("pub")
        for path in expand(m.group(1).replace("\n", " ").replace(" ", "")):
            yield line, path, reexport


def expand(tree: str) -> list[str]:
    depth = 0
    for i, c in enumerate(tree):
        if c == "{":
            if depth == 0:
                prefix, inner = tree[:i], tree[i + 1:tree.rindex("}")]
                parts, level, start = [], 0, 0
                for j, d in enumerate(inner):
                    level += d == "{"
                    level -= d == "}"
                    if d == "," and level == 0:
                        parts.append(inner[start:j])
                        start = j + 1
                parts.append(inner[start:])
                return [p for part in parts if part for p in expand(prefix + part)]
            depth += 1
    return [re.sub(r"\bas\b.*", "", tree)]


def resolve(module, path, modules, reexports=None):
    """The module that defines what `path`, written in `module`, names: the deepest module on
    the path, followed through `pub use` re-exports (a facade's names lead to their source)."""
    target, rest = walk(module, path, modules)
    if target is None:
        return None
    seen = set()
    while reexports and rest and rest[0] in reexports.get(target, {}) and (target, rest[0]) not in seen:
        seen.add((target, rest[0]))
        target = reexports[target][rest[0]]
    return target


def walk(module, path, modules):
    segs = [s for s in path.split("::") if s]
    if not segs:
        return None, []
    if segs[0] == "crate":
        base, segs = (), segs[1:]
    elif segs[0] in ("super", "self"):
        base = module
        while segs and segs[0] in ("super", "self"):
            if segs[0] == "super":
                base = base[:-1]
            segs = segs[1:]
    else:
        # A child module named directly (`mod x; … x::f()`), else an outside crate.
        if module + (segs[0],) not in modules:
            return None, []
        base = module
    target = base
    while segs and target + (segs[0],) in modules:
        target, segs = target + (segs[0],), segs[1:]
    return target, segs


def graph():
    files = sorted(SRC.rglob("*.rs"))
    modules = {module_of(f) for f in files}
    texts = {module_of(f): strip_comments(f.read_text()) for f in files}
    # Re-exports: module -> {name: the module its `pub use` takes it from}.
    reexports: dict[tuple, dict[str, tuple]] = {}
    for m, text in texts.items():
        for _, path, reexport in use_trees(text):
            if not reexport:
                continue
            src, rest = walk(m, path, modules)
            # `pub use a::b as c` re-exports `b` under the name `c`.
            last = path.split("::")[-1].split(" as ")[-1].strip()
            # A glob names no item: what it re-exports is found by its own name.
            if src is not None and rest and last != "*":
                reexports.setdefault(m, {})[last] = src
    edges: dict[tuple, dict[tuple, list[str]]] = {}
    for f in files:
        m = module_of(f)
        text = texts[m]
        found = []
        for line, path, reexport in use_trees(text):
            found.append((line, path, reexport))
        for mm in re.finditer(r"\b(?:crate|super)(?:::\w+)+", text):
            found.append((text.count("\n", 0, mm.start()) + 1, mm.group(0), False))
        for line, path, reexport in found:
            t = resolve(m, path, modules, reexports)
            if t is None or t == m or t == ():
                continue
            if t[: len(m)] == m and (reexport or m == ()):
                continue  # a parent's facade over its children (and lib.rs's, over all)
            # A child using its parent is an edge to the parent module's own items.
            edges.setdefault(m, {}).setdefault(t, []).append(f"{f.relative_to(ROOT)}:{line}: {path}")
    return modules, edges


def cycles(modules, edges):
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    sys.setrecursionlimit(10000)

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, {}):
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
                out.append(sorted(comp))

    for v in sorted(modules):
        if v not in index:
            visit(v)
    return out


def blank_comments_and_literals(text: str) -> str:
    """`text` with comments, strings and character literals blanked (newlines kept), so that
    braces count only as code."""
    out, i, n = [], 0, len(text)
    while i < n:
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i) + 2
        elif (m := re.match(r'r(#*)"', text[i:i + 8])) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            end = '"' + m.group(1)
            j = text.find(end, i + len(m.group(0))) + len(end)
        elif text[i] == '"':
            j = i + 1
            while text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            j += 1
        elif m := re.match(r"'(\\.|[^\\'])'|'\\u\{[0-9a-fA-F]+\}'", text[i:i + 12]):
            j = i + len(m.group(0))
        else:
            out.append(text[i])
            i += 1
            continue
        out.append(re.sub(r"[^\n]", " ", text[i:j]))
        i = j
    return "".join(out)


def functions():
    """(lines, "path:line name") of every function with a body in the library's code."""
    found = []
    for root in CODE:
        for f in sorted((ROOT / root).rglob("*.rs")):
            s = blank_comments_and_literals(f.read_text())
            for m in re.finditer(r"\bfn\s+(\w+)", s):
                k, depth = m.end(), 0
                while k < len(s):  # the body's brace, or `;` for a declaration
                    c = s[k]
                    depth += c in "(<["
                    depth -= c in ")>]"
                    if depth <= 0 and c in ";{":
                        break
                    k += 1
                if k >= len(s) or s[k] == ";":
                    continue
                level, j = 0, k
                while j < len(s):
                    level += s[j] == "{"
                    level -= s[j] == "}"
                    if level == 0:
                        break
                    j += 1
                first = s.count("\n", 0, m.start()) + 1
                found.append((s.count("\n", 0, j) + 2 - first, f"{f.relative_to(ROOT)}:{first} {m.group(1)}"))
    return sorted(found, reverse=True)


def name(m):
    return "::".join(m) or "crate"


def main():
    modules, edges = graph()
    if "--graph" in sys.argv:
        for m in sorted(edges):
            print(f"{name(m)} -> {', '.join(name(t) for t in sorted(edges[m]))}")
        return 0
    if "--functions" in sys.argv:
        for lines, where in functions()[:10]:
            print(lines, where)
        return 0
    problems = lean()
    for comp in cycles(modules, edges):
        lines = [f"module loop: {' <-> '.join(name(m) for m in comp)}"]
        members = set(comp)
        for m in comp:
            for t, why in sorted(edges.get(m, {}).items()):
                if t in members:
                    lines.append(f"  {name(m)} -> {name(t)}: {why[0]}" + (f" (+{len(why) - 1})" if len(why) > 1 else ""))
        problems.append("\n".join(lines))
    long = [(lines, where) for lines, where in functions() if lines > MAX_FN_LINES]
    problems += [f"{where}: {lines} lines, longer than {MAX_FN_LINES} (split it into named steps)" for lines, where in long]
    for p in problems:
        print(p, file=sys.stderr)
    if problems:
        return 1
    print(f"layers: {len(modules)} modules, no loop; the library's dependencies are lean; no function over {MAX_FN_LINES} lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())
