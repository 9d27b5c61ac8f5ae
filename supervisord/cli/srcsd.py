"""``srcsd``: the safety supervisor service (one per robot configuration)."""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence

from supervisord.config import check_config_main, load_config
from supervisord.errors import ConfigError, SrcsError

EXIT_CONFIG = 1


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="srcsd", description=__doc__)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--config", metavar="FILE", help="run with this robot configuration")
    group.add_argument(
        "--check-config", metavar="FILE", help="validate the configuration and exit (0 = valid)"
    )
    parser.add_argument("--verbose", action="store_true", help="log every link event")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.check_config:
        return check_config_main(args.check_config)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="srcsd: %(levelname)s: %(message)s",
        stream=sys.stderr,
    )
    try:
        config = load_config(args.config)
    except ConfigError as error:
        # The daemon refuses to start on a bad configuration (docs/configuration.md).
        print(f"srcsd: {error}", file=sys.stderr)
        return EXIT_CONFIG
    # Imported after the configuration is valid: python-can and gpiod load only when needed.
    from supervisord.daemon.assemble import build_api, build_supervisor  # noqa: PLC0415

    api = None
    try:
        api = build_api(config)
        supervisor = build_supervisor(config, api)
    except (SrcsError, OSError) as error:
        # A start that fails after the socket was made removes it (issue 11: a failed start
        # left a stale api.sock; the next start would replace it, but clients saw a path that
        # looked served). close() removes the file only if it is still ours.
        if api is not None:
            api.close()
        print(f"srcsd: cannot start: {error}", file=sys.stderr)
        return EXIT_CONFIG
    logging.getLogger("srcsd").info(
        "robot %s: %s, %d outputs",
        config.robot.name,
        supervisor.link.description,
        len(supervisor.outputs),
    )
    return supervisor.run()


if __name__ == "__main__":
    sys.exit(main())
