"""Write the suites' definition files from the code: ``python -m acc_gym.suites.generate [NAME ...]``.

Run it only to create a new suite (a new name); a released suite's file must not change
(the tests check that the code still regenerates it exactly). Each file is written
atomically (a temporary file in ``acc_gym/suites/data``, then ``os.replace``).
"""

from __future__ import annotations

import os
import sys
import tempfile

from acc_gym.suites import PINNED, data_path, definition_hash, file_text, list_suites, read_definition, template


def write(name: str) -> str:
    definition = template(name).materialise()
    path = data_path(name)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(file_text(definition))
        os.chmod(tmp, 0o644)  # package data: readable by all (mkstemp makes it private)
        read_definition(tmp)  # what was written reads back
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return str(path)


def main(argv=None) -> int:
    names = (sys.argv[1:] if argv is None else argv) or list_suites()
    for name in names:
        path = write(name)
        digest = definition_hash(read_definition(path))
        pinned = PINNED.get(name)
        note = "pinned" if pinned == digest else (f"NOT the pinned {pinned[:12]}..." if pinned else
                                                  "not pinned yet: add it to acc_gym.suites.PINNED")
        print(f"{path}  sha256 {digest} ({note})")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
