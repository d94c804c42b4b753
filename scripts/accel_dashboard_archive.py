"""The dashboard's read-only view of the lab archive (scripts/accel_archive.py, docs/design.md
section 13, docs/dashboard.md): every device with its records, and the newest records of each
device with the nine parameters and their expanded uncertainties, and the control chart of each
rig's check standard (~check_standards: rig -> serial; scripts/accel_history.py control_chart),
as plain dicts for the page.

The archive is only read: an archive whose schema is not at the newest revision is reported, not
migrated (scripts/archive does that)."""

import accel_archive as aa
import accel_history as ah

MAX_RECORDS = 10  # newest records per device shown


class ArchiveView:
    def __init__(self, url, check_standards=None):
        self.check_standards = {str(rig): str(serial)
                                for rig, serial in (check_standards or {}).items()}
        self.url = aa.resolve_url(url)
        self.shown_url = aa.display_url(self.url)
        self.engine = None

    def _engine(self):
        if self.engine is None:
            engine = aa.create_engine(self.url)
            with engine.connect() as connection:
                revision = aa.current_revision(connection)
            if revision != aa.head_revision():
                engine.dispose()
                raise aa.ArchiveError("archive %s is at schema revision %s, not %s: run "
                                      "`rosrun accel_intrinsics archive list` once to upgrade it"
                                      % (self.shown_url, revision, aa.head_revision()))
            self.engine = engine
        return self.engine

    def read(self):
        """{"url", "error", "devices": [{serial, rig, records, latest}], "histories": {serial:
        [{time, rig, method, model, values, expanded}] newest last}, "charts": {rig: {serial,
        reference, points: [{time, deviation, expanded}], flags}}} (every record of the rig's
        check standard on that rig, oldest first); errors in "error"."""
        view = {"url": self.shown_url, "error": "", "devices": [], "histories": {}, "charts": {}}
        try:
            engine = self._engine()
            for serial, rig, count, latest in aa.list_devices(engine):
                view["devices"].append({"serial": serial, "rig": rig, "records": int(count),
                                        "latest": aa.iso(latest)})
            for serial in sorted({d["serial"] for d in view["devices"]}):
                view["histories"][serial] = [
                    {"time": aa.iso(r["time"]), "rig": r["rig"], "method": r["method"],
                     "model": r["model"], "values": r["values"], "expanded": r["expanded"]}
                    for r in aa.fetch_records(engine, device=serial)[-MAX_RECORDS:]]
            for rig, serial in sorted(self.check_standards.items()):
                chart = ah.control_chart(aa.fetch_records(engine, device=serial, rig=rig))
                view["charts"][rig] = {
                    "serial": serial, "reference": chart["reference"], "flags": chart["flags"],
                    "points": [{"time": p["time"], "deviation": p["deviation"],
                                "expanded": p["expanded"]} for p in chart["points"]]}
        except Exception as e:  # noqa: BLE001 (a database error of any driver: shown, retried)
            view["error"] = aa.scrub(aa.first_line(e), self.url)
            if self.engine is not None:
                self.engine.dispose()
                self.engine = None
        return view
