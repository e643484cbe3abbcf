#!/usr/bin/env python3
"""How big the point-cloud path's repair is (issue: one curve stage instead of a repair
chain, with fewer tuning numbers): in crates/core/src/repair/*.rs and
crates/core/src/levelset/orient.rs, outside their test modules,

- lines of code: lines with code on them, comments and blank lines left out;
- tolerances: the fields of `repair::Tolerances` (each a number a user may set);
- constants: numeric `const` items;
- inline numbers: numeric literals in the code other than 0, 1, 2, 0.5 and powers of
  ten used as guards (1e-9 and the like), outside `const` items and `Tolerances`'
  `Default`, and other than exponents (`powi`, `powf`). Each is a threshold written where
  it is used; 3.0 in `3.0 * sigma` counts, as a choice of how many deviations, and so
  do a few that are arithmetic (a Hermite basis's 3, a sort's penalty).

The count is mechanical: a number with its reason written beside it counts as much as
one without. Usage: scripts/repair-size.py [ROOT] (default: the repository).
"""
import os
import re
import sys

# The repository this script is in, though it be run through a link.
ROOT = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.realpath(__file__)), "..")
FILES = sorted(
    [os.path.join("crates/core/src/repair", f) for f in os.listdir(os.path.join(ROOT, "crates/core/src/repair")) if f.endswith(".rs")]
    + ["crates/core/src/levelset/orient.rs"]
)
NUMBER = re.compile(r"(?<![\w.])(\d+(?:_\d+)*(?:\.\d+)?(?:e-?\d+)?)(?:f64|usize|u32|i32)?(?![\w.])")
PLAIN = {0.0, 1.0, 2.0, 0.5}


def code_lines(text):
    """The file's lines before its test module, with comments stripped."""
    out = []
    for line in text.splitlines():
        if line.strip().startswith("#[cfg(test)]"):
            break
        code = re.sub(r"//.*", "", line)
        # String literals hold messages, not thresholds.
        code = re.sub(r'"(?:[^"\\]|\\.)*"', '""', code)
        out.append(code)
    return out


def main():
    lines = consts = inline = 0
    fields = 0
    per_file = []
    for rel in FILES:
        text = open(os.path.join(ROOT, rel)).read()
        code = code_lines(text)
        n_lines = sum(1 for c in code if c.strip())
        n_consts = n_inline = 0
        in_struct = in_default = False
        depth = 0
        for c in code:
            s = c.strip()
            if rel.endswith("repair/mod.rs"):
                if s.startswith("pub struct Tolerances"):
                    in_struct = True
                elif in_struct and s == "}":
                    in_struct = False
                elif in_struct and re.match(r"pub \w+:", s):
                    fields += 1
                if s.startswith("impl Default for Tolerances"):
                    in_default, depth = True, 0
                if in_default:
                    depth += c.count("{") - c.count("}")
                    if depth <= 0 and "}" in c:
                        in_default = False
                    continue
            if re.match(r"(pub(\([\w:]+\))? )?const \w+: (f64|usize|u32|i32)", s):
                n_consts += 1
                continue
            # Exponents are arithmetic, not thresholds.
            c = re.sub(r"\.pow[if]\([^)]*\)", "", c)
            for m in NUMBER.finditer(c):
                v = float(m.group(1).replace("_", ""))
                if v in PLAIN or (v < 1e-5 and v > 0):
                    continue
                n_inline += 1
        per_file.append((rel, n_lines, n_consts, n_inline))
        lines += n_lines
        consts += n_consts
        inline += n_inline
    print("| file | lines of code | constants | inline numbers |")
    print("|---|---:|---:|---:|")
    for rel, a, b, c in per_file:
        print(f"| {rel} | {a} | {b} | {c} |")
    print(f"| all | {lines} | {consts} | {inline} |")
    print(f"\nTuning numbers: {fields} tolerances + {consts} constants + {inline} inline = "
          f"{fields + consts + inline}")


if __name__ == "__main__":
    main()
