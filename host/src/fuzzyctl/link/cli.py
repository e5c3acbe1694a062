"""``fuzzyctl --port PORT ...`` commands (registered on the main click group by fuzzyctl.cli).

The link options are top-level (``fuzzyctl --port /dev/ttyUSB0 --baud 921600 info``) so every
device command shares them; each command is a thin wrapper around one function of
:mod:`fuzzyctl.link.device`.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ..errors import FatalError


class LinkOptions:
    port: str | None = None
    baud: int = 115200
    timeout: float = 1.0
    retries: int = 5
    trace: bool = False


opts = LinkOptions()


def _setter(attr):
    def cb(ctx, param, value):
        if value is not None:
            setattr(opts, attr, value)
        return value
    return cb


def _open():
    from .transport import Link

    if not opts.port:
        raise FatalError("this command talks to the device: give the port first, e.g. "
                         "fuzzyctl --port /dev/ttyUSB0 info (a pty path from `fuzzystereo serve --link pty` works too)")
    link = Link(opts.port, opts.baud, opts.timeout, opts.retries, opts.trace)
    link.hello()
    return link


def register(app: click.Group, config_group: click.Group, console: Console) -> None:
    def _say(text: str) -> None:
        console.print(text, soft_wrap=True, highlight=False)

    app.params += [
        click.Option(["--port"], expose_value=False, callback=_setter("port"), help="Device serial port or pty path."),
        click.Option(["--baud"], type=int, expose_value=False, callback=_setter("baud"), help="Baud rate [default 115200]."),
        click.Option(["--timeout"], type=click.FloatRange(0.01), expose_value=False, callback=_setter("timeout"),
                     help="Seconds to wait for each answer [default 1]."),
        click.Option(["--retries"], type=click.IntRange(0, 100), expose_value=False, callback=_setter("retries"),
                     help="Resends of a request before giving up [default 5]."),
        click.Option(["--trace"], is_flag=True, default=None, expose_value=False, callback=_setter("trace"),
                     help="Hex-dump every frame with time deltas (stderr)."),
    ]

    @app.command("info")
    def info_cmd() -> None:
        """Handshake with the device: firmware, protocol layout, uptime, active config."""
        from .device import info_json

        with _open() as link:
            i = link.info
        if not sys.stdout.isatty():
            click.echo(info_json(i))
            return
        t = Table(title=f"device on {opts.port}")
        t.add_column("field")
        t.add_column("value")
        states = {v: k for k, v in link.schema.enums["run_state"].items()}
        for k, v in i.items():
            if k == "state":
                v = states.get(v, v)
            elif k == "config_id":
                v = f"{v:08x}"
            t.add_row(k, v.hex() if isinstance(v, bytes) else str(v))
        console.print(t)

    @config_group.command("validate")
    @click.argument("path", type=click.Path(path_type=Path))
    def config_validate(path: Path) -> None:
        """Validate a config file against the schema (offline; same as `config check`)."""
        from ..config import load_config

        load_config(path)
        _say(f"{path}: OK")

    @config_group.command("pull")
    @click.argument("file", type=click.Path(path_type=Path), required=False)
    def config_pull_cmd(file: Path | None) -> None:
        """The device's active config (to FILE, or stdout)."""
        from .device import config_pull

        with _open() as link:
            text = config_pull(link)
            cid = link.info["config_id"]
        if file:
            file.write_bytes(text)
            _say(f"wrote {file} ({len(text)} bytes, config id {cid:08x}, {link.info['config_source']})")
        else:
            click.echo(text.decode("utf-8", "replace"), nl=False)

    @config_group.command("push")
    @click.argument("file", type=click.Path(path_type=Path, exists=True, dir_okay=False))
    def config_push_cmd(file: Path) -> None:
        """Validate FILE locally, send it, let the device verify the CRC, validate and commit it."""
        from rich.progress import Progress

        from ..config import load_config
        from .device import config_push

        load_config(file)  # the same schema the device validates against: fail here first
        text = file.read_bytes()
        with _open() as link, Progress(console=console, transient=True, disable=not sys.stdout.isatty()) as prog:
            task = prog.add_task(f"pushing {file.name}", total=len(text))
            r = config_push(link, text, progress=lambda d, t: prog.update(task, completed=d))
        _say(f"pushed {file} ({r.bytes} bytes, CRC {r.crc:08x} verified by the device); "
                      f"active config id {r.config_id:08x}")

    @config_group.command("diff")
    @click.argument("file", type=click.Path(path_type=Path, exists=True, dir_okay=False))
    def config_diff_cmd(file: Path) -> None:
        """Resolved values that differ between the device's active config and FILE."""
        from ..config import load_config, parse_config
        from .device import config_pull

        with _open() as link:
            dev_text = config_pull(link).decode("utf-8")
        dev = parse_config(dev_text, source="device")
        loc = load_config(file)
        diffs = []
        devd = dev.as_dict()
        for sec, fields in loc.as_dict().items():
            for k, v in fields.items():
                dv = devd.get(sec, {}).get(k)
                if dv != v:
                    diffs.append((f"{sec}.{k}", dv, v))
        if not diffs:
            _say(f"device config = {file} (all resolved values equal)")
            return
        t = Table(title=f"device vs {file}")
        for c in ("field", "device", str(file)):
            t.add_column(c)
        for k, a, b in diffs:
            t.add_row(k, str(a), str(b))
        console.print(t)

    @app.group("logs")
    def logs_group() -> None:
        """Device log files: list, pull (resumable, verified), convert."""

    @logs_group.command("list")
    def logs_list_cmd() -> None:
        """Log files on the device."""
        from .device import log_list

        with _open() as link:
            files = log_list(link)
        t = Table(title=f"logs on {opts.port}")
        t.add_column("id", justify="right")
        t.add_column("bytes", justify="right")
        for f in files:
            t.add_row(str(f["id"]), str(f["size"]))
        console.print(t)

    @logs_group.command("pull")
    @click.option("--all", "all_", is_flag=True, help="Every file (default: the newest only).")
    @click.option("--out", type=click.Path(path_type=Path), default=Path("logs"), show_default=True)
    @click.option("--format", "fmt", type=click.Choice(["raw", "csv", "json"]), default="raw", show_default=True,
                  help="Also write each log as CSV or JSON beside the raw file.")
    @click.option("--window", type=click.IntRange(1, 16), default=8, show_default=True, help="Requests in flight.")
    def logs_pull_cmd(all_: bool, out: Path, fmt: str, window: int) -> None:
        """Copy logs to OUT (resuming an interrupted pull) and verify every record."""
        from .device import log_list, log_pull
        from .logfile import parse_log, to_csv, to_json

        with _open() as link:
            files = log_list(link)
            ids = [f["id"] for f in files] if all_ else [f["id"] for f in files[-1:]]
            t0 = time.monotonic()
            pulled = log_pull(link, out, ids, window=window)
            dt = time.monotonic() - t0
            stats = dict(link.stats)
        total_new = sum(p.new_bytes for p in pulled)
        for p in pulled:
            state = "ok" if p.good else "CORRUPT"
            _say(f"{p.path}: {p.size} bytes ({p.new_bytes} new), {p.records} records verified, {state}"
                          + (f" — {escape(p.note)}" if p.note else ""))
            if fmt != "raw":
                parsed = parse_log(p.path.read_bytes(), link.schema)
                conv = p.path.with_suffix("." + fmt)
                conv.write_text(to_csv(parsed) if fmt == "csv" else to_json(parsed))
                _say(f"  wrote {conv}")
        rate = total_new / dt if dt > 0 else 0.0
        _say(f"{total_new} bytes in {dt:.2f} s ({rate:.0f} B/s; link {opts.baud / 10:.0f} B/s); "
                      f"{stats['resent']} resends")
        if any(not p.good for p in pulled):
            raise FatalError("some log files failed verification (see above)")

    @app.command("monitor")
    @click.option("--count", type=click.IntRange(1), default=None, help="Stop after N updates.")
    @click.option("--interval", type=click.FloatRange(0.02), default=0.2, show_default=True, help="Seconds between updates.")
    @click.option("--plain", is_flag=True, help="Plain lines even on a terminal.")
    def monitor_cmd(count: int | None, interval: float, plain: bool) -> None:
        """Live telemetry: fps, stage timings, obstacles, motors, error counters."""
        from .monitor import run_monitor

        with _open() as link:
            run_monitor(link, console, count, interval, plain or not sys.stdout.isatty())

    @app.command("snapshot")
    @click.option("--out", type=click.Path(path_type=Path), required=True, help="Directory for the dump files.")
    def snapshot_cmd(out: Path) -> None:
        """Current frame's inputs and stage outputs (dump format; then `fuzzyctl compare OUT`)."""
        from .device import snapshot

        with _open() as link:
            paths = snapshot(link, out)
        _say(f"wrote {len(paths)} files to {out} (CRC-checked); compare with: fuzzyctl compare {out}")

    for action, doc in (("estop", "Emergency stop (sticky until clear-estop)."), ("pause", "Pause the robot."),
                        ("resume", "Resume after pause."), ("clear-estop", "Clear an e-stop.")):
        def make(action=action, doc=doc):
            @app.command(action, help=doc)
            def _cmd() -> None:
                from .device import control

                with _open() as link:
                    control(link, action)
                _say(f"{action}: acknowledged by the device")
        make()
