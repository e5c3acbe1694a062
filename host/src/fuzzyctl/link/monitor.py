"""``fuzzyctl monitor``: live telemetry. A rich Live layout on a terminal; one plain line per
update otherwise (or with --plain), so it can be logged or tested."""

from __future__ import annotations

import time

from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from .device import telemetry
from .transport import Link

_CLS = {0: ("unknown", "white"), 1: ("static", "yellow"), 2: ("moving", "magenta")}


def _dist_colour(d: float) -> str:
    return "bold red" if d < 0.5 else "orange1" if d < 1.0 else "yellow" if d < 2.0 else "green"


def plain_line(t: dict, states: dict) -> str:
    obs = " ".join(f"{_CLS.get(o['cls'], ('?',))[0]}#{o['track_id']}@{o['distance_m']:.2f}m" for o in t["obstacles"])
    stages = " ".join(f"{s['name']}={s['ms']:.1f}" for s in t["stages"])
    return (f"frame {t['frame_id']} fps {t['fps']:.1f} state {states.get(t['state'], t['state'])} | {stages} | "
            f"obstacles {len(t['obstacles'])}{(' ' + obs) if obs else ''} | cmd v={t['cmd_v_mps']:.2f} "
            f"w={t['cmd_w_radps']:.2f} | motors L={t['motor_left']:+.2f} R={t['motor_right']:+.2f} | pose "
            f"{t['pose_x_m']:.2f},{t['pose_y_m']:.2f},{t['pose_yaw_deg']:.0f}deg | errors rx={t['rx_errors']} "
            f"tx_drop={t['tx_dropped']} log_drop={t['log_dropped']} frame={t['frame_errors']} | {t['source']}")


def render(t: dict, states: dict, port: str):
    head = Text(f"{port}  frame {t['frame_id']}  {t['fps']:.1f} fps  state {states.get(t['state'], t['state'])}  "
                f"source: {t['source']}", style="bold")
    st = Table(title="stage timing [ms]", expand=True)
    st.add_column("stage")
    st.add_column("ms", justify="right")
    st.add_column("", ratio=1)
    total = sum(s["ms"] for s in t["stages"]) or 1.0
    for s in t["stages"]:
        st.add_row(s["name"], f"{s['ms']:.1f}", Text("█" * int(40 * s["ms"] / total), style="cyan"))
    ob = Table(title=f"obstacles ({len(t['obstacles'])})", expand=True)
    for c in ("track", "class", "distance [m]", "lateral [m]", "width [m]"):
        ob.add_column(c)
    for o in sorted(t["obstacles"], key=lambda o: o["distance_m"]):
        name, colour = _CLS.get(o["cls"], ("?", "white"))
        ob.add_row(str(o["track_id"]), Text(name, style=colour), Text(f"{o['distance_m']:.2f}", style=_dist_colour(o["distance_m"])),
                   f"{o['lateral_m']:+.2f}", f"{o['width_m']:.2f}")
    mo = Text(f"command v {t['cmd_v_mps']:+.2f} m/s  w {t['cmd_w_radps']:+.2f} rad/s   motors L {t['motor_left']:+.2f} "
              f"R {t['motor_right']:+.2f}   pose ({t['pose_x_m']:.2f}, {t['pose_y_m']:.2f}) m {t['pose_yaw_deg']:.0f} deg")
    er = Text(f"errors: link rx {t['rx_errors']}  tx dropped {t['tx_dropped']}  log dropped {t['log_dropped']}  "
              f"frames {t['frame_errors']}", style="red" if any(t[k] for k in ("rx_errors", "tx_dropped", "log_dropped", "frame_errors")) else "dim")
    return Group(head, st, ob, mo, er)


def run_monitor(link: Link, console: Console, count: int | None, interval: float, plain: bool) -> None:
    states = {v: k for k, v in link.schema.enums["run_state"].items()}
    n = 0
    if plain:
        while count is None or n < count:
            console.print(plain_line(telemetry(link), states), soft_wrap=True, highlight=False, markup=False)
            n += 1
            time.sleep(interval)
        return
    with Live(console=console, refresh_per_second=10) as live:
        while count is None or n < count:
            live.update(render(telemetry(link), states, link.port_name))
            n += 1
            time.sleep(interval)
