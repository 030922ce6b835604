"""The block a measuring tool writes into a document between its two marker lines (README.md's
bench table, docs/performance.md's live and chain tables, docs/logs.md's calibration table)."""

import sys


def write_block(path, begin, end, body):
    """Replace what lies between the lines `begin` and `end` of `path` with `body` (the lines
    between them, markers excluded); exits naming the file when the markers are missing,
    repeated or out of order."""
    with open(path) as f:
        text = f.read()
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        sys.exit(f"{path}: needs one line {begin} followed by one line {end}")
    before, rest = text.split(begin, 1)
    after = rest.split(end, 1)[1]
    with open(path, "w") as f:
        f.write(before + begin + "\n" + body + "\n" + end + after)
