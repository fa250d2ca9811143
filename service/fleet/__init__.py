"""The fleet service: every wheel followed across sites and days (issue 16).

| module | holds |
|---|---|
| ``keys`` | the fleet's Zenoh keys (alarms, wheel and alarm queryables, catch-up) |
| ``entry`` | one stored diagnosis (``Entry``), read from a ``Diagnosis`` |
| ``migrations`` | the database schema as numbered migrations (SQLite and PostgreSQL) |
| ``store`` | ``Store``: history, sites, wheels and alarms in SQLite or PostgreSQL |
| ``trend`` | weighted least-squares growth trend and the predicted limit crossings |
| ``alarms`` | ``FleetAlarm`` and the rules that raise one (escalation, forecast) |
| ``history`` | a wheel's history document (entries + trend), as the queryable answers |
| ``service`` | ``FleetService``: subscribe, catch up, store, alarm, answer queries |
| ``dashboard`` | the web page (``--http``): sites, alarms, vehicles, a wheel's plot |
| ``plot`` | the wheel page's server-side SVG plot |

The command line is ``service.cli.fleet`` (``railtwin fleet serve|wheel|alarms``), the
demo ``service.cli.fleet_demo`` (``make fleet-demo``).
See docs/fleet.md.
"""
