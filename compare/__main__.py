import os
import sys

from compare.cli import main

try:
    sys.exit(main(sys.argv[1:]))
except BrokenPipeError:            # e.g. `python -m compare list | head`
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    sys.exit(0)
