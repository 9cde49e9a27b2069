"""MkDocs hooks of the documentation site (mkdocs.yml): the C API page, generated at build time.

``reference/c-api.md`` is not a file of docs/: the build emits the C of one target (``ur5``,
``reduced_order``, the default discretisation) into a temporary folder and turns its header's
comments into Markdown (``c_api_markdown``). The page is therefore the header a user receives,
comment for comment; a function added to the template (codegen/pipeline/templates/observer.h.in)
appears on the next build. tests/test_docs_site.py checks that every declared function is on it.
"""
from __future__ import annotations

import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

C_API_PAGE = "reference/c-api.md"
C_API_TARGET = {"robot": "ur5", "family": "reduced_order"}


@dataclass
class Block:
    """A run of declarations of the header under one comment (or none)."""

    comment: str = ""
    defines: list = field(default_factory=list)      # (name, value, trailing comment)
    code: list = field(default_factory=list)         # typedefs, enums, structs: verbatim
    functions: list = field(default_factory=list)    # (name, declaration)


def _uncomment(text):
    """The text of a C block comment: delimiters and leading `` * `` removed, lines kept."""
    text = text.strip()
    text = re.sub(r"^/\*+", "", text)
    text = re.sub(r"\*+/$", "", text)
    lines = [re.sub(r"^\s*\* ?", "", line) if line.lstrip().startswith("*") else line.strip()
             for line in text.splitlines()]
    return "\n".join(lines).strip()


def parse_header(text):
    """(file comment, [Block]) of a generated header: each comment with the declarations under it.

    A block ends at a blank line or at the next comment; a function without its own comment
    (``_estimate_dt`` after ``_estimate``) joins the block above it."""
    lines = text.splitlines()
    i, file_comment, blocks = 0, "", []
    current = Block()

    def close():
        nonlocal current
        if current.comment or current.defines or current.code or current.functions:
            blocks.append(current)
        current = Block()

    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        if stripped.startswith("/*"):
            chunk = [line]
            while "*/" not in lines[i]:
                i += 1
                chunk.append(lines[i])
            comment = _uncomment("\n".join(chunk))
            if not file_comment and not blocks and not current.comment:
                file_comment = comment
            else:
                close()
                current.comment = comment
        elif not stripped:
            if current.defines or current.code:
                close()
        elif re.match(r"#(ifndef|ifdef|endif|if|else)\b", stripped) or stripped in (
                'extern "C" {', '} /* extern "C" */', "}"):
            pass
        elif stripped.startswith("#define"):
            m = re.match(r"#define\s+(\w+)\s*(.*?)\s*(?:/\*\s*(.*?)\s*\*/)?\s*$", stripped)
            if m and m.group(2):                       # the include guard has no value
                current.defines.append((m.group(1), m.group(2), m.group(3) or ""))
        elif stripped.startswith(("typedef", "enum")):
            chunk = [line]
            if "{" in line:
                while not re.match(r"\s*}", lines[i]):
                    i += 1
                    chunk.append(lines[i])
            current.code.append("\n".join(chunk))
        else:                                          # a function declaration, maybe on lines
            chunk = [stripped]
            while not chunk[-1].endswith(";"):
                i += 1
                chunk.append(lines[i].strip())
            decl = " ".join(chunk)
            name = re.search(r"(\w+)\s*\(", decl).group(1)
            current.functions.append((name, decl))
        i += 1
    close()
    return file_comment, blocks


def _escape(text):
    return text.replace("|", "\\|").replace("<", "&lt;").replace("*", "\\*").replace("_", "\\_")


def c_api_markdown(header_text, header_name):
    """The C API page (Markdown) of one generated header."""
    prefix = header_name[:-2]
    file_comment, blocks = parse_header(header_text)
    out = [
        "# C API",
        "",
        f"Generated from the comments of `{header_name}`, the header the build emits for "
        f"`ur5` with `reduced_order` at the default discretisation (the header of any other "
        f"target has the same functions with its own prefix, sizes and slots: replace "
        f"`{prefix}` and `{prefix.upper()}` by the target's name). How to build and link the "
        f"folder: [The generated C](../guide/c-code.md).",
        "",
        "## The header's own summary",
        "",
        "```text",
        file_comment,
        "```",
        "",
        "## Types, sizes and constants",
        "",
    ]
    functions = []
    for block in blocks:
        if block.functions:
            functions.append(block)
            continue
        if block.comment:
            out += [block.comment.replace("\n", " "), ""]
        if block.defines:
            out += ["| macro | value | meaning |", "|---|---|---|"]
            out += [f"| `{n}` | `{_escape(v) if '|' in v else v}` | {_escape(c)} |"
                    for n, v, c in block.defines]
            out.append("")
        for code in block.code:
            out += ["```c", code, "```", ""]
    out += ["## Functions", "",
            "Every function returns a status (`OK` = 0, see the enum above) unless it returns "
            "void or a size; on an error the state is left unchanged.", ""]
    for block in functions:
        for name, _ in block.functions:
            out += [f"### `{name}`", ""]
            break
        out += ["```c"] + [decl for _, decl in block.functions] + ["```", ""]
        if len(block.functions) > 1:
            out += ["Also: " + ", ".join(f"`{n}`" for n, _ in block.functions[1:]) + ".", ""]
        if block.comment:
            out += [_escape(block.comment).replace("\n", " "), ""]
    return "\n".join(out) + "\n"


def emitted_header():
    """(text, file name) of the header of C_API_TARGET, emitted into a temporary folder."""
    from codegen.pipeline.emit import emit
    from codegen.pipeline.targets_file import make_target
    target, _ = make_target(dict(C_API_TARGET), where="docs C API")
    with tempfile.TemporaryDirectory() as tmp:
        folder = emit(target, tmp)
        header = folder / f"{folder.name}.h"
        return header.read_text(), header.name


def on_files(files, config):
    """Add the generated C API page to the site."""
    from mkdocs.structure.files import File
    text, name = emitted_header()
    files.append(File.generated(config, C_API_PAGE, content=c_api_markdown(text, name)))
    return files
