"""The fleet's web dashboard (``railtwin fleet serve --http HOST:PORT``).

Plain HTML from the standard library's ``http.server`` in a thread; plots are inline
SVG drawn on the server (``service.fleet.plot``): no script, style sheet or font is
fetched from anywhere.

| path | page |
|---|---|
| ``/`` | the sites (health, last passage), the open alarms, a vehicle search |
| ``/vehicle?q=V`` | the wheels of vehicle V (``V*``: every vehicle starting with V) |
| ``/wheel/<vehicle_id>/<wheelset>/<side>`` | history table and trend plots |
| ``/api/status``, ``/api/sites``, ``/api/alarms``, ``/api/wheel/<V>/<ws>/<side>`` | JSON |
"""

from __future__ import annotations

import html
import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs, quote, urlsplit

from service.fleet.keys import WheelIdError, parse_wheel_id
from service.fleet.plot import wheel_svg
from service.fleet.service import FleetService

STYLE = """body{font-family:sans-serif;margin:1.5em;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;
text-align:left;font-size:14px}th{background:#f0f0f0}.ok{color:#080}.watch{color:#a80}
.inspect{color:#d60}.remove{color:#c00;font-weight:bold}.critical{color:#c00;font-weight:bold}
.warning{color:#d60}.info{color:#a80}a{color:#2050b0}small{color:#666}"""


def _e(x: object) -> str:
    return html.escape(str(x))


def _date(t: float | None) -> str:
    return "-" if t is None else time.strftime("%Y-%m-%d %H:%M", time.gmtime(t))


def _page(title: str, body: str, refresh: int | None = None) -> str:
    meta = f'<meta http-equiv="refresh" content="{refresh}">' if refresh else ""
    return (
        f"<!DOCTYPE html><html><head><meta charset='utf-8'>{meta}<title>{_e(title)}</title>"
        f"<style>{STYLE}</style></head><body><p><a href='/'>railtwin fleet</a></p>"
        f"<h1>{_e(title)}</h1>{body}</body></html>"
    )


def _wheel_link(wheel_id: str) -> str:
    return f"<a href='/wheel/{quote(wheel_id)}'>{_e(wheel_id)}</a>"


def _alarms_table(alarms: list[dict[str, Any]]) -> str:
    if not alarms:
        return "<p id='no-alarms'>no open alarms</p>"
    rows = "".join(
        f"<tr class='alarm'><td>{_date(a['raised_at'])}</td><td class='{_e(a['severity'])}'>"
        f"{_e(a['severity'])}</td><td>{_wheel_link(a['wheel_id'])}</td><td>{_e(a['kind'])}</td>"
        f"<td>{_e(a['reason'])}</td><td><small>{_e(', '.join(a['evidence'][-4:]))}</small></td>"
        "</tr>"
        for a in alarms
    )
    return (
        "<table id='alarms'><tr><th>raised (UTC)</th><th>severity</th><th>wheel</th>"
        f"<th>kind</th><th>reason</th><th>evidence</th></tr>{rows}</table>"
    )


class Dashboard:
    """The HTTP server in a daemon thread; ``url`` once started."""

    def __init__(self, service: FleetService, host: str, port: int) -> None:
        self.service = service
        dashboard = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:
                dashboard._handle(self)

            def log_message(self, format: str, *args: Any) -> None:
                pass

        self._server = ThreadingHTTPServer((host, port), Handler)
        self._server.daemon_threads = True
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self._server.server_address[:2]
        return f"http://{host!s}:{port}/"

    def start(self) -> None:
        self._thread = threading.Thread(
            target=self._server.serve_forever, name="fleet-http", daemon=True
        )
        self._thread.start()

    def stop(self) -> None:
        self._server.shutdown()
        self._server.server_close()

    # --- routing -----------------------------------------------------------------------

    def _handle(self, req: BaseHTTPRequestHandler) -> None:
        url = urlsplit(req.path)
        path, query = url.path, parse_qs(url.query)
        try:
            if path == "/":
                self._send(req, 200, self.index_page())
            elif path == "/vehicle":
                self._send(req, 200, self.vehicle_page(query.get("q", [""])[0].strip()))
            elif path.startswith("/wheel/"):
                status, text = self.wheel_page(path[len("/wheel/") :])
                self._send(req, status, text)
            elif path.startswith("/api/"):
                status, doc = self.api(path[len("/api/") :], query)
                self._send(req, status, json.dumps(doc), "application/json")
            else:
                self._send(req, 404, _page("not found", f"<p>{_e(path)}: no such page</p>"))
        except Exception as exc:
            self._send(req, 500, _page("error", f"<p>{_e(type(exc).__name__)}: {_e(exc)}</p>"))

    def _send(
        self,
        req: BaseHTTPRequestHandler,
        status: int,
        text: str,
        ctype: str = "text/html; charset=utf-8",
    ) -> None:
        body = text.encode("utf-8")
        req.send_response(status)
        req.send_header("Content-Type", ctype)
        req.send_header("Content-Length", str(len(body)))
        req.send_header("Cache-Control", "no-store")
        req.end_headers()
        req.wfile.write(body)

    # --- pages -------------------------------------------------------------------------

    def sites(self) -> list[dict[str, Any]]:
        rows = {s.site_id: s for s in self.service.store.sites()}
        out = []
        for site in sorted(set(rows) | set(self.service.health)):
            h = self.service.health.get(site)
            r = rows.get(site)
            out.append(
                {
                    "site_id": site,
                    "health": None
                    if h is None
                    else {
                        k: h.get(k)
                        for k in ("seen_at", "uptime", "passages_done", "errors", "queue_depth")
                    },
                    "last_timestamp": None if r is None else r.last_timestamp,
                    "last_passage_id": None if r is None else r.last_passage_id,
                    "last_verdict": None if r is None else r.last_verdict,
                    "diagnoses": 0 if r is None else r.diagnoses,
                }
            )
        return out

    def index_page(self) -> str:
        now = time.time()
        rows = []
        for s in self.sites():
            h = s["health"]
            if h is None:
                health = "<span class='watch'>no answer</span>"
            else:
                age = now - (h["seen_at"] or 0)
                state = "up" if age < 60 else f"last seen {age / 60:.0f} min ago"
                health = (
                    f"<span class='{'ok' if age < 60 else 'watch'}'>{state}</span> "
                    f"<small>{h['passages_done']} passages, {h['errors']} errors, queue "
                    f"{h['queue_depth']}</small>"
                )
            rows.append(
                f"<tr class='site'><td>{_e(s['site_id'])}</td><td>{health}</td>"
                f"<td>{_date(s['last_timestamp'])}</td><td>{_e(s['last_passage_id'] or '-')}"
                f"</td><td class='{_e(s['last_verdict'])}'>{_e(s['last_verdict'] or '-')}"
                f"</td><td>{s['diagnoses']}</td></tr>"
            )
        sites = (
            (
                "<table id='sites'><tr><th>site</th><th>health</th><th>last passage (UTC)</th>"
                "<th>passage</th><th>verdict</th><th>diagnoses</th></tr>"
                + "".join(rows)
                + "</table>"
            )
            if rows
            else "<p>no site seen yet</p>"
        )
        alarms = self.service.alarms_document()["alarms"]
        st = self.service.status()
        body = (
            "<form action='/vehicle'><label>vehicle <input name='q' placeholder='V123 or V1*'>"
            "</label> <button>search</button></form>"
            f"<h2>open alarms ({len(alarms)})</h2>{_alarms_table(alarms)}"
            f"<h2>sites</h2>{sites}"
            f"<p><small>{st['stored']} diagnoses stored this run, {st['duplicates']} duplicates "
            f"dropped, {st['rejected']} refused; database {_e(st['db'])}</small></p>"
        )
        return _page("railtwin fleet", body, refresh=10)

    def vehicle_page(self, q: str) -> str:
        if not q:
            return _page("vehicle", "<p>give a vehicle id</p>")
        wheels = self.service.store.wheels(q)
        if not wheels:
            return _page(
                f"vehicle {q}", "<p id='no-wheels'>no wheel of this vehicle has been diagnosed</p>"
            )
        rows = "".join(
            f"<tr class='wheel'><td>{_wheel_link(w.wheel_id)}</td><td>{_date(w.last_timestamp)}"
            f"</td><td class='{_e(w.last_verdict)}'>{_e(w.last_verdict)}</td></tr>"
            for w in wheels
        )
        return _page(
            f"vehicle {q}",
            "<table id='wheels'><tr><th>wheel</th><th>last diagnosis "
            f"(UTC)</th><th>verdict</th></tr>{rows}</table>",
        )

    def wheel_page(self, wheel_id: str) -> tuple[int, str]:
        try:
            parse_wheel_id(wheel_id)
        except WheelIdError as exc:
            return 400, _page("bad wheel id", f"<p>{_e(exc)}</p>")
        doc = self.service.wheel_document(wheel_id)
        if doc is None:
            return 404, _page(f"wheel {wheel_id}", "<p>no diagnosis of this wheel</p>")
        rows = []
        for h in doc["history"]:
            f = h["flat"]
            flat = (
                "-"
                if f is None
                else (
                    f"{f['kind']} {f['length'] * 1e3:.1f} mm "
                    f"[{f['length_low'] * 1e3:.1f}–{f['length_high'] * 1e3:.1f}]"
                )
            )
            fl, sp = h["peak_force_at_line_speed"], h["speed"]
            rows.append(
                f"<tr class='entry'><td>{_date(h['timestamp'])}</td><td>{_e(h['site_id'])}</td>"
                f"<td>{_e(h['passage_id'])}</td><td class='{_e(h['verdict'])}'>{_e(h['verdict'])}"
                f"</td><td>{flat}</td><td>{'-' if fl is None else f'{fl / 1e3:.0f}'}</td>"
                f"<td>{'-' if sp is None else f'{sp:.1f}'}</td></tr>"
            )
        trend_lines = []
        for name, label, scale, unit in (
            ("flat_length", "flat length", 1e3, "mm"),
            ("peak_force_at_line_speed", "peak force at line speed", 1e-3, "kN"),
        ):
            t = doc["trend"][name]
            if t is None:
                trend_lines.append(f"<li>{label}: not determined</li>")
                continue
            cs = []
            for c in t["crossings"]:
                if c["status"] == "not_growing":
                    cs.append(f"{c['level']}: not growing")
                elif c["status"] == "reached":
                    cs.append(f"{c['level']}: reached")
                else:
                    span = (
                        ""
                        if c["earliest"] is None
                        else (
                            f" (95 %: {_date(c['earliest'])} – "
                            f"{_date(c['latest']) if c['latest'] is not None else 'open'})"
                        )
                    )
                    cs.append(f"{c['level']} {c['limit'] * scale:g} {unit}: {_date(c['at'])}{span}")
            trend_lines.append(
                f"<li class='trend'>{label}: {t['slope_per_day'] * scale:+.3g} ± "
                f"{t['slope_se_per_day'] * scale:.2g} {unit}/day over {t['points']} diagnoses; "
                + "; ".join(cs)
                + "</li>"
            )
        alarms = [r.json() for r in self.service.store.alarms(open_only=False, wheel_id=wheel_id)]
        body = (
            f"<p>last verdict <b class='{_e(doc['last_verdict'])}'>{_e(doc['last_verdict'])}</b>"
            f", {len(doc['history'])} diagnoses at "
            f"{len({h['site_id'] for h in doc['history']})} site(s)</p>"
            f"<div id='plots'>{wheel_svg(doc)}</div><h2>trend</h2><ul>{''.join(trend_lines)}</ul>"
            "<p><small>distance run: not in the messages (no odometer reading); plotted against "
            "date only</small></p>"
            f"<h2>alarms</h2>{_alarms_table(alarms)}"
            "<h2>history</h2><table id='history'><tr><th>date (UTC)</th><th>site</th>"
            "<th>passage</th><th>verdict</th><th>flat [95 %]</th><th>F at line speed kN</th>"
            f"<th>speed m/s</th></tr>{''.join(rows)}</table>"
            f"<p><a href='/api/wheel/{quote(wheel_id)}'>JSON</a></p>"
        )
        return 200, _page(f"wheel {wheel_id}", body)

    def api(self, what: str, query: dict[str, list[str]]) -> tuple[int, Any]:
        if what == "status":
            return 200, self.service.status()
        if what == "sites":
            return 200, self.sites()
        if what == "alarms":
            return 200, self.service.alarms_document(query.get("all", [""])[0] in ("1", "true"))
        if what.startswith("wheel/"):
            wid = what[len("wheel/") :]
            try:
                parse_wheel_id(wid)
            except WheelIdError as exc:
                return 400, {"error": "bad_wheel_id", "message": str(exc)}
            doc = self.service.wheel_document(wid)
            return (
                (200, doc)
                if doc is not None
                else (404, {"error": "unknown_wheel", "wheel_id": wid})
            )
        return 404, {"error": "not_found"}
