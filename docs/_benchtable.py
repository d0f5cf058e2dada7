"""Read the comparison table printed by ``python -m benchmarks.compare`` into rows of
dicts. Values are read as tokens, in column order: a missing time prints as ``-`` and
its ratio column is then left blank."""

import re

_UNITS = {"ns": 1e-9, "µs": 1e-6, "us": 1e-6, "ms": 1e-3, "s": 1.0}


_TOKEN = re.compile(r"[\d.]+ (?:ns|µs|us|ms|s)(?!\w)|[\d.]+x?|-")


def _is_ratio(name):
    return name == "qa/add" or name.endswith("/qa")


def _value(text):
    """Seconds for '2.36 µs', a float for '6.39x' or '5.43', None for '-' or blank."""
    text = text.strip()
    if text in ("", "-"):
        return None
    m = re.fullmatch(r"([\d.]+)\s*(ns|µs|us|ms|s)", text)
    if m:
        return float(m.group(1)) * _UNITS[m.group(2)]
    return float(text.rstrip("x"))


def read(path):
    """(header comment lines, rows); a row maps 'operation', 'N', 'dtype' and each
    column name to its value (seconds or a ratio); ratio columns are '<peer> /qa'."""
    comments, rows, names, edges = [], [], None, None
    with open(path, encoding="utf-8") as f:
        for line in f:
            line = line.rstrip("\n")
            if line.startswith("#") and names is None:
                comments.append(line.lstrip("# "))
            elif names is None and line.startswith("operation"):
                spans = [(m.group(), m.end()) for m in re.finditer(r"\S+", line)]
                names, edges, previous = [], [], None
                for name, end in spans[3:]:          # after 'operation', 'N', 'dtype'
                    names.append(f"{previous} /qa" if name == "/qa" else name)
                    edges.append(end)
                    previous = name
            elif names and line.strip() and not set(line) <= set("-"):
                m = re.match(r"^(?P<op>.*?)\s+(?P<n>\d+)?\s*(?P<dtype>float\d+)", line)
                if m is None:                        # the end of the table (targets follow)
                    break
                row = {"operation": m.group("op").strip(), "dtype": m.group("dtype"),
                       "N": int(m.group("n")) if m.group("n") else None}
                tokens = _TOKEN.findall(line[m.end():])
                k = 0
                for i, name in enumerate(names):
                    if name in row:                  # the ratio after a missing time
                        continue
                    token = tokens[k] if k < len(tokens) else "-"
                    k += 1
                    row[name] = _value(token)
                    if token == "-" and i + 1 < len(names) and _is_ratio(names[i + 1]):
                        row[names[i + 1]] = None
                rows.append(row)
    return comments, rows


#: Peer ratio columns of the README's compact table, in order: (README heading, column here).
README_COLUMNS = [("÷ np.add", "qa/add"), ("scipy", "scipy /qa"), ("numpy-quaternion", "numpy-quat /qa"),
                  ("quaternionic", "quaternion /qa")]


def _time(seconds):
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9)):
        if seconds >= scale:
            value = seconds / scale
            return f"{value:.3g} {unit}"
    return f"{seconds / 1e-9:.3g} ns"


def readme_table(path):
    """The README's compact benchmark table (markdown lines) from a run saved at `path`:
    one row per operation at N = 10⁶ float64 (and the size-less resample rows, and the
    10⁴-key tracks), with quatarray's time, its ratio to np.add, each peer's ratio, and
    the N = 1 ratio for scipy where the operation is also timed on one element."""
    _, rows = read(path)
    big = [r for r in rows if r["dtype"] == "float64" and r["N"] in (1_000_000, None)
           and "10 keys" not in r["operation"]]
    one = {r["operation"]: r for r in rows if r["dtype"] == "float64" and r["N"] == 1}
    names = ["operation", "quatarray"] + [h for h, _ in README_COLUMNS] + ["N = 1: scipy"]
    lines = ["| " + " | ".join(names) + " |", "|---|" + "--:|" * (len(names) - 1)]

    def ratio(row, key):
        value = None if row is None else row.get(key)
        return "–" if value is None else f"{value:.2f}"

    for r in big:
        cells = [r["operation"].replace("10000", "10⁴"), "–" if r.get("quatarray") is None else _time(r["quatarray"])]
        cells += [ratio(r, key) for _, key in README_COLUMNS]
        cells.append(ratio(one.get(r["operation"]), "scipy /qa"))
        lines.append("| " + " | ".join(cells) + " |")
    return lines   # operations timed on one element only stay in the guide's table


if __name__ == "__main__":   # python docs/_benchtable.py docs/guide/benchmark_table.txt
    import sys
    print("\n".join(readme_table(sys.argv[1])))
