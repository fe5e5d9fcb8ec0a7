#!/usr/bin/env python3
"""Internal-link check for the book (book/src), run by scripts/test.sh's `book` check.

    python3 scripts/book_links.py [BOOK_SRC]     check BOOK_SRC (default: book/src next to this
                                                 script's folder); exit 1 on any problem
    python3 scripts/book_links.py --self-test    check the checker on a small book in a temporary
                                                 folder

For every Markdown page under BOOK_SRC it checks that
  - every relative link or image, inline `[text](path#anchor)`, `<path>` form or a reference
    definition `[ref]: path`, names a file inside BOOK_SRC;
  - every `#anchor` (on another page or on the same one) is the id of a heading on that page,
    computed as mdBook 0.4 computes it (see `heading_ids`);
  - every page is listed in SUMMARY.md, and every SUMMARY.md entry exists.
http(s), mailto and other URL-scheme links are not checked, nor anything inside fenced code
blocks or inline code. Each problem is printed as `book/src/page.md:LINE: ...`.

Standard library only: it runs with any python3, before or without the project venv.
"""

import os
import re
import sys
import tempfile
from urllib.parse import unquote

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
# An inline link or image target: `](target)` or `](target "title")` or `](<target>)`.
INLINE = re.compile(r"\]\(\s*(<[^>\n]*>|[^()\s]*(?:\([^()\s]*\)[^()\s]*)*)(?:\s+(?:\"[^\"]*\"|'[^']*'))?\s*\)")
REFDEF = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(<[^>\n]*>|\S+)", re.M)
HEADING = re.compile(r"^ {0,3}(#{1,6})[ \t]+(.*?)[ \t]*#*[ \t]*$")
SETEXT = re.compile(r"^ {0,3}(=+|-+)[ \t]*$")
CUSTOM_ID = re.compile(r"\{\s*#([^\s}]+)[^}]*\}\s*$")
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def blank_fences(text):
    """The text with fenced code blocks replaced by spaces, so that offsets and line numbers stay
    the same and nothing inside them is taken for a link or a heading."""
    out = []
    fence = None
    for line in text.splitlines(keepends=True):
        m = FENCE.match(line)
        if fence is None and m:
            fence = m.group(1)
            out.append(blank(line))
        elif fence is not None:
            if m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence) \
                    and line.strip() == m.group(1):
                fence = None
            out.append(blank(line))
        else:
            out.append(line)
    return "".join(out)


def blank_code(text):
    """blank_fences, and inline code spans blanked too (for links; a heading keeps its code)."""
    text = blank_fences(text)
    # Inline code: a run of N backticks up to the next run of exactly N (may span lines).
    return re.sub(r"(?<!`)(`+)(?!`).*?(?<!`)\1(?!`)", lambda m: blank(m.group(0)), text, flags=re.S)


def blank(s):
    return re.sub(r"[^\n]", " ", s)


def slug(heading):
    """mdBook 0.4's id for a heading's text (utils::id_from_content over the rendered HTML):
    tags and the entities &lt; &gt; &amp; &#39; &quot; removed, then each alphanumeric character
    kept (ASCII lowercased), `_` and `-` kept, whitespace becomes `-`, everything else dropped."""
    parts = re.split(r"((?<!`)`+(?!`).*?(?<!`)`+(?!`))", heading)
    text = ""
    for i, part in enumerate(parts):
        if i % 2:  # inline code: its text is kept as is (`<name>` becomes &lt;name&gt;: `name`)
            text += part
            continue
        part = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", part)  # a link renders as its text
        part = re.sub(r"<[^>]*>", "", part)  # inline HTML
        text += re.sub(r"\\(.)", r"\1", part)  # backslash escapes
    # The entities mdBook removes (&amp; &lt; &gt; &#39; &quot;) leave no alphanumeric behind.
    text = text.strip().lstrip("#").strip()
    out = []
    for ch in text:
        if ch.isalnum() or ch in "_-":
            out.append(ch.lower() if ch.isascii() else ch)
        elif ch.isspace():
            out.append("-")
    return "".join(out)


def heading_ids(text):
    """The ids of a page's headings, duplicates numbered `-1`, `-2`, ... as mdBook does; a
    `{#custom-id}` attribute replaces the computed one."""
    lines = blank_fences(text).splitlines()
    ids = set()
    seen = {}
    for i, line in enumerate(lines):
        m = HEADING.match(line)
        content = m.group(2) if m else None
        if content is None and i > 0 and SETEXT.match(line) and lines[i - 1].strip() \
                and not HEADING.match(lines[i - 1]):
            content = lines[i - 1].strip()
        if content is None:
            continue
        custom = CUSTOM_ID.search(content)
        if custom:
            ids.add(custom.group(1))
            continue
        base = slug(content)
        n = seen.get(base, 0)
        seen[base] = n + 1
        ids.add(base if n == 0 else f"{base}-{n}")
    return ids


def links(text):
    """(line, target) for every link target outside code."""
    clean = blank_code(text)
    found = []
    for pattern in (INLINE, REFDEF):
        for m in pattern.finditer(clean):
            target = m.group(1)
            if target.startswith("<") and target.endswith(">"):
                target = target[1:-1]
            found.append((clean.count("\n", 0, m.start(1)) + 1, target))
    return sorted(found)


def summary_entries(text):
    """(line, path) for every `[title](path)` in SUMMARY.md (draft chapters `()` have none)."""
    return [(line, target) for line, target in links(text) if target]


def check(src, shown=None):
    """The problems found in the book whose source folder is `src`, as printable lines."""
    src = os.path.abspath(src)
    shown = shown if shown is not None else os.path.relpath(src)
    problems = []
    pages = {}
    for root, dirs, files in os.walk(src):
        dirs.sort()
        for name in sorted(files):
            if name.endswith(".md"):
                path = os.path.join(root, name)
                with open(path, encoding="utf-8") as f:
                    pages[os.path.relpath(path, src).replace(os.sep, "/")] = f.read()
    ids = {}

    def ids_of(page):
        if page not in ids:
            ids[page] = heading_ids(pages[page])
        return ids[page]

    def where(page, line):
        return f"{shown}/{page}:{line}"

    summary = "SUMMARY.md"
    for page, text in sorted(pages.items()):
        if page == summary:
            continue  # its entries are checked below
        for line, target in links(text):
            if not target or SCHEME.match(target) or target.startswith("//"):
                continue
            path, _, anchor = target.partition("#")
            path = unquote(path.split("?", 1)[0])
            if path.startswith("/"):
                problems.append(f"{where(page, line)}: absolute link {target!r}: make it relative")
                continue
            if path:
                resolved = os.path.normpath(os.path.join(os.path.dirname(page), path))
                resolved = resolved.replace(os.sep, "/")
                if resolved == ".." or resolved.startswith("../"):
                    problems.append(f"{where(page, line)}: link {target!r} points outside "
                                    f"{shown} (mdBook does not copy it)")
                    continue
                if not os.path.isfile(os.path.join(src, resolved)):
                    problems.append(f"{where(page, line)}: broken link {target!r}: "
                                    f"no file {shown}/{resolved}")
                    continue
            else:
                resolved = page
            if anchor and resolved.endswith(".md") and unquote(anchor) not in ids_of(resolved):
                problems.append(f"{where(page, line)}: broken anchor {target!r}: "
                                f"{shown}/{resolved} has no heading with the id {anchor!r}")

    if summary not in pages:
        return problems + [f"{shown}/{summary}:1: missing: mdBook needs it"]
    listed = set()
    for line, target in summary_entries(pages[summary]):
        path = unquote(target.partition("#")[0])
        resolved = os.path.normpath(path).replace(os.sep, "/")
        listed.add(resolved)
        if SCHEME.match(target):
            problems.append(f"{where(summary, line)}: entry {target!r} is not a page of the book")
        elif resolved not in pages:
            problems.append(f"{where(summary, line)}: entry {target!r}: no page {shown}/{resolved}")
    for page in sorted(pages):
        if page != summary and page not in listed:
            problems.append(f"{where(page, 1)}: page is not listed in {shown}/{summary}")
    return problems


def self_test():
    """Builds a small book with one of each problem (and the cases that must pass) in a
    temporary folder and checks that exactly the expected problems are reported."""
    files = {
        "SUMMARY.md": "# Summary\n\n[Intro](intro.md)\n\n- [Guide](guide/page.md)\n"
                      "- [Gone](gone.md)\n- [Draft]()\n",
        "intro.md": (
            "# Intro\n\n"
            "## Statistics & `stats.json`: what's in it?\n\n"
            "## Statistics & `stats.json`: what's in it?\n\n"
            "Setext heading\n--------------\n\n"
            "## A heading {#custom}\n\n"
            "### `sources.<name>.fps` <em>and</em> [x](guide/page.md)\n\n"
            "[ok](guide/page.md) [ok](guide/page.md#deep-section) ![ok](img/a.png)\n"
            "[ok](#statistics--statsjson-whats-in-it) [ok](#statistics--statsjson-whats-in-it-1)\n"
            "[ok](#setext-heading) [ok](#custom) [ok](https://example.com/x.md)\n"
            "[ok](#sourcesnamefps-and-x)\n"
            "[ok, inline code](`not/a.md`) `[ok](in/code.md)`\n"
            "[bad](missing.md)\n"  # line 19
            "[bad](guide/page.md#nope)\n"  # line 20
            "[bad](#nope)\n"  # line 21
            "```md\n[ok](in/fence.md)\n```\n"
            "[a multi-line\nlink](../outside.md)\n"  # target on line 26
            "[ref]: gone-too.md\n"  # line 27
        ),
        "guide/page.md": "# Page\n\n### Deep section\n\n[ok](../intro.md#intro)\n",
        "orphan.md": "# Orphan\n",
        "img/a.png": "",
    }
    expected = [
        "B/SUMMARY.md:6: entry 'gone.md': no page B/gone.md",
        "B/intro.md:19: broken link 'missing.md': no file B/missing.md",
        "B/intro.md:20: broken anchor 'guide/page.md#nope': B/guide/page.md has no heading with"
        " the id 'nope'",
        "B/intro.md:21: broken anchor '#nope': B/intro.md has no heading with the id 'nope'",
        "B/intro.md:26: link '../outside.md' points outside B (mdBook does not copy it)",
        "B/intro.md:27: broken link 'gone-too.md': no file B/gone-too.md",
        "B/orphan.md:1: page is not listed in B/SUMMARY.md",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for name, text in files.items():
            path = os.path.join(tmp, name)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        got = check(tmp, shown="B")
    if sorted(got) != sorted(expected):
        print("book_links.py --self-test: FAILED", file=sys.stderr)
        for line in sorted(set(expected) - set(got)):
            print(f"  expected, not reported: {line}", file=sys.stderr)
        for line in sorted(set(got) - set(expected)):
            print(f"  reported, not expected: {line}", file=sys.stderr)
        return 1
    print(f"book_links.py --self-test: ok ({len(expected)} problems found as expected)")
    return 0


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    if len(argv) > 2 or (len(argv) == 2 and argv[1].startswith("-")):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    src = argv[1] if len(argv) == 2 else os.path.join(os.path.dirname(__file__), "..", "book", "src")
    if not os.path.isdir(src):
        print(f"book_links.py: no folder {src}", file=sys.stderr)
        return 2
    problems = check(src, shown=os.path.relpath(os.path.abspath(src)))
    for problem in problems:
        print(problem)
    pages = sum(f.endswith(".md") for _, _, fs in os.walk(src) for f in fs)
    if problems:
        print(f"book_links.py: {len(problems)} problem(s) in {pages} pages", file=sys.stderr)
        return 1
    print(f"book_links.py: {pages} pages, every internal link and anchor resolves, every page "
          f"is in SUMMARY.md")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
