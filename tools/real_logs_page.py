"""The table of docs/guide/real-logs.md, regenerated from the real arms' logs: every judge of
codegen.evaluate.scenarios.real_judge (the clock, identification, velocity, the user's flow).

    python tools/real_logs_page.py [--work DIR] [--page docs/guide/real-logs.md]

The logs are read from $CODEGEN_REAL_LOGS (or ../shared/data/real beside the repository); the
commands' outputs and figures.json go to --work (default a temporary folder).
"""
import argparse
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from codegen.evaluate.scenarios import real_judge, real_logs  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", help="folder of the commands' outputs (default: a temporary one)")
    ap.add_argument("--page", default=str(ROOT / "docs" / "guide" / "real-logs.md"))
    args = ap.parse_args(argv)
    if real_logs.folder() is None:
        print(real_logs.skip_reason(), file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.work or tmp)
        fig = real_judge.figures(real_judge.Bed(work))
        (work / "figures.json").write_text(json.dumps(fig, indent=1, default=str) + "\n")
        print(real_judge.table(fig))
        print(f"{real_judge.write_page(fig, args.page)} written; figures.json in {work}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
