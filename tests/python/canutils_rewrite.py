"""Reads a can-utils capture with python-can's CanutilsLogReader and writes it again with its
CanutilsLogWriter: the interop check of jointctl's candump writer (python-can must parse every
line) and reader (it must decode python-can's output to the same joint log).

usage: canutils_rewrite.py IN.log OUT.log   (prints the number of frames)
"""
import sys

import can


def main(src, dst):
    n = 0
    with can.CanutilsLogWriter(dst) as w:
        for msg in can.CanutilsLogReader(src):
            w.on_message_received(msg)
            n += 1
    print(n)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
