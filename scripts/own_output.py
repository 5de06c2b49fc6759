"""The scripts' rule for their output files: a script rewrites a file it wrote before (its
marker line sits in the first lines) and never one it did not, such as a catalogue of the
user's own under the same name. Imported by the scripts that write catalogues."""
import os


def foreign(path, marker, lines=3):
    """Whether `path` exists and none of its first `lines` lines contains `marker`: a file this
    script did not write, which it must leave alone."""
    if not os.path.exists(path):
        return False
    with open(path, encoding="utf-8", errors="replace") as f:
        return not any(marker in f.readline() for _ in range(lines))
