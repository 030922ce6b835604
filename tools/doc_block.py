"""The block a measuring tool writes into a document between its two marker lines (README.md's
bench table, docs/performance.md's live and chain tables, docs/logs.md's calibration table)."""

import argparse
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


def block_args(doc):
    """The command line of a tool that writes a block, parsed before it does any work: `-h`
    shows `doc`, `--print` sends the block to stdout instead of into its document, and anything
    else is an error (so a mistyped option never rewrites a document)."""
    ap = argparse.ArgumentParser(description=doc,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--print", action="store_true",
                    help="print the block instead of writing it into its document")
    return ap.parse_args()


def emit_block(to_stdout, path, begin, end, body):
    """`body` to stdout, or into `path` between `begin` and `end` ([`write_block`])."""
    if to_stdout:
        print(body)
    else:
        write_block(path, begin, end, body)
