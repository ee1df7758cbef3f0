#!/usr/bin/env python3
"""Import circles inside the workspace's crates: a module that imports one that imports it back,
directly or through others. Reads every `use` of every crate's `src/` (test modules left out)
and resolves `crate::`, `super::`, `self::` and child-module paths to the module that holds the
name; prints each circle with the imports that close it and exits 1 where there is one.

    python3 scripts/import-cycles.py [ROOT]
"""

import os
import re
import sys

USE = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", re.M)


def module_path(src, file):
    parts = os.path.relpath(file, src)[: -len(".rs")].split(os.sep)
    return tuple(parts[:-1] if parts[-1] in ("mod", "lib", "main") else parts)


def imported_names(rest):
    """The paths a `use` names below its prefix: `a::b`, or each of `a::{b, c::d}`."""
    if "{" not in rest:
        return [[p for p in rest.split("::") if p.strip()]]
    head = [p for p in rest[: rest.index("{")].split("::") if p.strip()]
    inner = rest[rest.index("{") + 1 : rest.rindex("}")]
    names = [x.strip() for x in re.split(r",(?![^{]*\})", inner) if x.strip()]
    return [head + [n.split("::")[0].split(" ")[0]] for n in names]


def edges_of(src):
    files = [os.path.join(d, f) for d, _, fs in os.walk(src) for f in fs if f.endswith(".rs")]
    modules = {module_path(src, f): f for f in files}
    edges = set()
    for module, file in modules.items():
        text = open(file, encoding="utf-8").read()
        text = text.split("#[cfg(test)]")[0]
        for use in USE.finditer(text):
            path = " ".join(use.group(1).split())
            if path.startswith("crate::"):
                base, rest = [], path[len("crate::"):]
            elif path.startswith(("super::", "self::")):
                base, rest = list(module), path
                while rest.startswith("super::"):
                    base, rest = base[:-1], rest[len("super::"):]
                rest = rest[len("self::"):] if rest.startswith("self::") else rest
            elif tuple(list(module) + [path.split("::")[0].strip("{ ")]) in modules:
                base, rest = list(module), path
            else:
                continue
            for name in imported_names(rest):
                target = base + [p.strip() for p in name]
                k = len(target)
                while k > 0 and tuple(target[:k]) not in modules:
                    k -= 1
                if tuple(target[:k]) != module:
                    edges.add((module, tuple(target[:k])))
    return edges


def circles(edges):
    """Strongly connected components of more than one module (Tarjan)."""
    graph = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(set(component))

    sys.setrecursionlimit(10000)
    for v in list(graph):
        if v not in index:
            visit(v)
    return found


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
    sources = [os.path.join(root, "src")] + [
        os.path.join(root, "crates", c, "src") for c in sorted(os.listdir(os.path.join(root, "crates")))
    ]
    name = lambda m: "::".join(m) or "(root)"
    bad = 0
    for src in filter(os.path.isdir, sources):
        edges = edges_of(src)
        for component in circles(edges):
            bad += 1
            print(f"{os.path.relpath(src, root)}: import circle")
            for a, b in sorted(edges):
                if a in component and b in component:
                    print(f"  {name(a)} -> {name(b)}")
    if bad:
        print(f"{bad} import circle(s): a module imports one that imports it back", file=sys.stderr)
        sys.exit(1)
    print("no import circles")


if __name__ == "__main__":
    main()
