"""`python -m codegen`: the command line (codegen.cli.main); a reader that closed the pipe
(`describe LOG | head`) ends it quietly with status 141, as a shell tool."""
import os
import sys

from .cli import main

status = main()
try:
    sys.stdout.flush()
except BrokenPipeError:
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    status = 141
raise SystemExit(status)
