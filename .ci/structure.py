#!/usr/bin/env python3
"""The house's shape, checked (issue 39): no non-test function over MAX lines, and no two modules
that import each other.

    python3 .ci/structure.py [ROOT] [--max-lines 150]

Sources: every crate's `src/` (crates/*/src, src, python/src). Test code is left out: a
`#[cfg(test)]` module to the end of its file, and files named tests.rs, testkit.rs or test_*.rs.

Function length: a function runs from its `fn` line to the first line that closes its indentation
(rustfmt's layout), both counted.

Circles: each `use` and each inline `crate::`/`super::`/`self::` path of a file is resolved to the
module it names (through `pub use` re-exports, so `crate::Dataset` counts as the module that
defines it). Two modules that are not nested in each other are compared as the two children of
their closest common ancestor that hold them; a circle is a set of such siblings that reach each
other (a strongly connected set), e.g. `data::dataset` using `data::import` while a file under
`import/` uses `dataset`. A module using its parent or its own children is no circle (that is how
a folder module works). Prints each circle with one import per direction and exits 1 if any
check fails.
"""
import os
import re
import sys

FN = re.compile(r"^(\s*)(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?fn\s+(\w+)")
PATH = re.compile(r"\b(crate|super|self)((?:::\w+)+)")


def crate_roots(root):
    roots = [os.path.join(root, "src"), os.path.join(root, "python", "src")]
    crates = os.path.join(root, "crates")
    roots += [os.path.join(crates, c, "src") for c in sorted(os.listdir(crates))]
    return [r for r in roots if os.path.isdir(r)]


def is_test_file(name):
    return name in ("tests.rs", "testkit.rs") or name.startswith("test_")


def non_test_lines(path):
    """The file's lines up to its `#[cfg(test)]` module (test code is not the house's shape)."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    end = next((i for i, l in enumerate(lines) if l.strip() == "#[cfg(test)]"), len(lines))
    return lines[:end]


def long_functions(path, lines, max_lines):
    out, i = [], 0
    while i < len(lines):
        m = FN.match(lines[i])
        if m and not lines[i].rstrip().endswith(";"):
            indent, j = m.group(1), i + 1
            while j < len(lines) and not (
                lines[j].startswith(indent + "}")
                and len(lines[j]) - len(lines[j].lstrip()) == len(indent)
            ):
                j += 1
            if j - i + 1 > max_lines:
                out.append((j - i + 1, path, i + 1, m.group(7)))
            i = j
        i += 1
    return out


def module_of(src_root, path):
    rel = os.path.relpath(path, src_root)[:-3].split(os.sep)
    if rel[-1] in ("lib", "main", "mod"):
        rel = rel[:-1]
    return tuple(rel)


def strip_comments_and_strings(text):
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    text = re.sub(r'r#*"(?:.|\n)*?"#*', '""', text)
    text = re.sub(r'"(?:\\.|[^"\\])*"', '""', text)
    text = re.sub(r"'(?:\\.|[^'\\])'", "' '", text)
    return re.sub(r"//[^\n]*", "", text)


def expand_use(tree):
    """`a::{b, c::{d, e}}` -> ['a::b', 'a::c::d', 'a::c::e'] (aliases and globs kept as written)."""
    tree = re.sub(r"\s+", " ", tree).strip()
    tree = re.sub(r"\s*([{},:])\s*", r"\1", tree)
    if not re.fullmatch(r"[\w:{}, *]+", tree) or tree.count("{") != tree.count("}"):
        return []  # not a use tree (a `use` inside a macro or a string the stripping missed)
    if "{" not in tree:
        return [tree]
    head, rest = tree.split("{", 1)
    inner = rest[: rest.rindex("}")]
    parts, depth, cur = [], 0, ""
    for ch in inner:
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
            continue
        depth += ch == "{"
        depth -= ch == "}"
        cur += ch
    parts.append(cur)
    return [p for part in parts if part for p in expand_use(head + part)]


class Crate:
    def __init__(self, src_root):
        self.root = src_root
        self.files = {}  # path -> (module, code without comments, lines)
        for dp, _, fs in os.walk(src_root):
            for f in sorted(fs):
                if f.endswith(".rs") and not is_test_file(f):
                    p = os.path.join(dp, f)
                    lines = non_test_lines(p)
                    code = strip_comments_and_strings("\n".join(lines))
                    self.files[p] = (module_of(src_root, p), code, lines)
        self.modules = {m for m, _, _ in self.files.values()}
        self.reexports = {}  # (module, name) -> path segments it re-exports
        for m, code, _ in self.files.values():
            for stmt in re.findall(r"\bpub(?:\([^)]*\))?\s+use\s+([^;]+);", code):
                for item in expand_use(stmt):
                    segs = item.split(" as ")[0].split("::")
                    name = item.split(" as ")[-1].split("::")[-1]
                    if name != "*":
                        self.reexports[(m, name)] = (m, segs)

    def absolute(self, module, segs):
        """Path segments as written in `module` -> absolute segments in this crate, or None."""
        if not segs:
            return None
        if segs[0] == "crate":
            return list(segs[1:])
        base, rest = list(module), list(segs)
        if rest[0] == "self":
            rest = rest[1:]
        elif rest[0] == "super":
            while rest and rest[0] == "super":
                if not base:
                    return None
                base, rest = base[:-1], rest[1:]
        else:
            if tuple(base + rest[:1]) not in self.modules:
                return None  # an external crate or a name in scope
        return base + rest

    def resolve(self, segs, depth=0):
        """The module that defines what absolute `segs` names (following `pub use`)."""
        k = len(segs)
        while k > 0 and tuple(segs[:k]) not in self.modules:
            k -= 1
        module = tuple(segs[:k])
        if k < len(segs) and depth < 8:
            target = self.reexports.get((module, segs[k]))
            if target is not None:
                at, written = target
                absolute = self.absolute(at, written)
                if absolute is not None:
                    return self.resolve(absolute + segs[k + 1:], depth + 1)
        return module

    def imports(self):
        """(importing module, imported module, file, line) for every crate-internal path."""
        for path, (module, code, _) in self.files.items():
            for m in re.finditer(r"\buse\s+([^;]+);", code):
                line = code.count("\n", 0, m.start()) + 1
                for item in expand_use(m.group(1)):
                    segs = item.split(" as ")[0].split("::")
                    segs = [s for s in segs if s not in ("*", "")]
                    absolute = self.absolute(module, segs)
                    if absolute is not None:
                        yield module, self.resolve(absolute), path, line
            for m in PATH.finditer(code):
                line = code.count("\n", 0, m.start()) + 1
                segs = [m.group(1)] + m.group(2).split("::")[1:]
                absolute = self.absolute(module, segs)
                if absolute is not None:
                    yield module, self.resolve(absolute), path, line


def circles(crate):
    edges = {}  # (parent, child a, child b) -> first (file, line)
    for src, dst, path, line in crate.imports():
        common = 0
        while common < min(len(src), len(dst)) and src[common] == dst[common]:
            common += 1
        if common == len(src) or common == len(dst):
            continue  # nested: a module and its ancestor or descendant
        key = (src[:common], src[common], dst[common])
        edges.setdefault(key, (path, line))
    by_parent = {}
    for (parent, a, b), where in edges.items():
        by_parent.setdefault(parent, {}).setdefault(a, {})[b] = where
    found = []
    for parent, graph in sorted(by_parent.items()):
        for component in strongly_connected(graph):
            if len(component) > 1:
                found.append((parent, sorted(component), graph))
    return found


def strongly_connected(graph):
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]
    nodes = set(graph) | {b for bs in graph.values() for b in bs}

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, {}):
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
            out.append(comp)

    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return out


def self_test():
    """The checks find what they are for: a circle through a re-export, a 151-line function."""
    import tempfile

    with tempfile.TemporaryDirectory() as root:
        src = os.path.join(root, "crates", "demo", "src")
        os.makedirs(os.path.join(src, "a"))
        write = lambda rel, text: open(os.path.join(src, rel), "w").write(text)
        write("lib.rs", "mod a;\nmod b;\nmod c;\npub use b::Thing;\n")
        write("a/mod.rs", "mod inner;\nuse crate::c::helper;\n")
        write("a/inner.rs", "pub fn f() -> crate::Thing { super::super::c::helper() }\n")
        body = "".join("    let _x = 1;\n" for _ in range(149))
        write("b.rs", "use crate::a::inner;\npub struct Thing;\nfn long() {\n" + body + "}\n")
        write("c.rs", "pub fn helper() {}\n#[cfg(test)]\nmod tests { use crate::a::inner; }\n")
        crate = Crate(src)
        found = [(p, sorted(c)) for p, c, _ in circles(crate)]
        assert found == [((), ["a", "b"])], found
        long = [x for path, (_, _, lines) in crate.files.items()
                for x in long_functions(path, lines, 150)]
        assert [(n, name) for n, _, _, name in long] == [(151, "long")], long
    print("structure.py self-test: a circle through a re-export and a 151-line function found")


def main():
    args = sys.argv[1:]
    if args == ["--self-test"]:
        return self_test()
    max_lines = 150
    if "--max-lines" in args:
        i = args.index("--max-lines")
        max_lines = int(args[i + 1])
        del args[i : i + 2]
    root = args[0] if args else "."
    failed = False
    long = []
    for src in crate_roots(root):
        crate = Crate(src)
        for path, (_, _, lines) in crate.files.items():
            long += long_functions(os.path.relpath(path, root), lines, max_lines)
        for parent, component, graph in circles(crate):
            failed = True
            name = os.path.relpath(os.path.dirname(src), root) or "."
            print(f"circle in {name}: " + " <-> ".join("::".join(parent + (c,)) for c in component))
            for a in component:
                for b in component:
                    if b in graph.get(a, {}):
                        path, line = graph[a][b]
                        print(f"    {'::'.join(parent + (a,))} uses {'::'.join(parent + (b,))}"
                              f" at {os.path.relpath(path, root)}:{line}")
    for n, path, line, name in sorted(long, reverse=True):
        print(f"function over {max_lines} lines: {path}:{line} {name} ({n} lines)")
    failed |= bool(long)
    if failed:
        print("split long functions into named steps; break a circle by moving the shared piece "
              "down into a module both use (docs: .ci/structure.py)")
        sys.exit(1)
    print(f"structure: no function over {max_lines} lines, no modules that import each other")


if __name__ == "__main__":
    main()
