"""The lab archive of calibration results and the device history (docs/design.md section 13).

One module behind scripts/archive and scripts/history (and the tests): SQLAlchemy Core (Debian's
python3-sqlalchemy 1.4) for one implementation over SQLite and PostgreSQL, Alembic migrations
(scripts/archive_migrations) for the versioned schema.

Concurrency: every write is one database transaction. SQLite transactions begin with BEGIN
IMMEDIATE (the write lock is taken at the start, so two writers queue instead of failing on a
lock upgrade); PostgreSQL's schema upgrade holds an advisory lock so two first-time writers do not
both create the tables. A duplicate (same input sha256, same result) is absorbed by the unique
constraint with INSERT ... ON CONFLICT DO NOTHING, so it is one record whoever wins.

A password in the URL is never printed: every message names the database by display_url().
"""

import datetime
import hashlib
import json
import math
import os
import re

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import make_url

ACCEL = ("u", "v", "w")
ANGLES = ("uv", "vw", "wu")
# The nine intrinsic parameters, named as in compare_results (docs/design.md section 9), with the
# result keys of the value, its standard uncertainty and its expanded uncertainty.
PARAMETERS = tuple(
    [("responsivity_" + a, "responsivity", "responsivity_std", "responsivity", a) for a in ACCEL] +
    [("angle_" + a, "angles_deg", "angles_std_deg", "angles_deg", a) for a in ANGLES] +
    [("offset_" + a, "offset", "offset_std", "offset", a) for a in ACCEL])
PARAMETER_NAMES = tuple(p[0] for p in PARAMETERS)
METHODS = ("gimbal", "positions", "tumble")
DEFAULT_K = 2.0
# Stamps before this are simulated clocks (sim_clock starts at 100 s), not dates.
EARLIEST_PLAUSIBLE_STAMP = 946684800.0  # 2000-01-01
MIGRATIONS_DIR = os.path.join(os.path.dirname(os.path.realpath(__file__)), "archive_migrations")
ADVISORY_LOCK_KEY = 0x61636365  # "acce": serializes schema upgrades on PostgreSQL

metadata = sa.MetaData()
# The schema at its newest revision (archive_migrations/versions: what each revision adds).
records = sa.Table(
    "records", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("device_serial", sa.String(200), nullable=False, index=True),
    sa.Column("rig", sa.String(200), nullable=False, index=True),
    sa.Column("time", sa.DateTime, nullable=False),  # UTC
    sa.Column("method", sa.String(20), nullable=False),
    sa.Column("local_gravity", sa.Float, nullable=False),
    sa.Column("model", sa.String(200), nullable=False),
    sa.Column("result_json", sa.Text, nullable=False),
    sa.Column("position_table", sa.Text, nullable=True),
    sa.Column("input_sha256", sa.String(64), nullable=False),
    sa.Column("result_sha256", sa.String(64), nullable=False),
    sa.Column("added_at", sa.DateTime, nullable=False),
    sa.Column("added_by", sa.String(200), nullable=False),
    sa.UniqueConstraint("input_sha256", "result_sha256", name="uq_records_input_result"),
)
parameters = sa.Table(
    "parameters", metadata,
    sa.Column("record_id", sa.Integer, sa.ForeignKey("records.id", ondelete="CASCADE"),
              primary_key=True),
    sa.Column("name", sa.String(40), primary_key=True),
    sa.Column("value", sa.Float, nullable=False),
    sa.Column("expanded", sa.Float, nullable=False),
    sa.Column("k", sa.Float, nullable=False),
)


class ArchiveError(Exception):
    """A bad input or an unusable archive: one line for the user."""


# --- URLs ----------------------------------------------------------------------------------------

def default_url():
    home = os.environ.get("ROS_HOME") or os.path.join(os.path.expanduser("~"), ".ros")
    return "sqlite:///" + os.path.join(home, "accel_intrinsics", "archive.db")


def resolve_url(url):
    """The URL given, else $ACCEL_INTRINSICS_ARCHIVE, else the default SQLite file."""
    return url or os.environ.get("ACCEL_INTRINSICS_ARCHIVE") or default_url()


def display_url(url):
    """The URL as it may be shown: the password replaced by ***."""
    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # not a URL: show its scheme only, it may hold anything
        return re.sub(r"//[^@/]*@", "//***@", str(url))


def scrub(text, url):
    """`text` without the URL's password (a driver's message may quote its arguments)."""
    try:
        password = make_url(url).password
    except Exception:
        password = None
    text = str(text)
    if password:
        text = text.replace(str(password), "***")
    return text


# --- Connection and schema -----------------------------------------------------------------------

def _sqlite_transactions(engine):
    # pysqlite starts transactions lazily and not before DDL; take them over so a schema upgrade
    # and every write is one real transaction, and take the write lock at once.
    @event.listens_for(engine, "connect")
    def _connect(dbapi_connection, _record):
        dbapi_connection.isolation_level = None
        dbapi_connection.execute("PRAGMA foreign_keys = ON")
        dbapi_connection.execute("PRAGMA busy_timeout = 60000")

    @event.listens_for(engine, "begin")
    def _begin(connection):
        connection.exec_driver_sql("BEGIN IMMEDIATE")


def create_engine(url):
    url = resolve_url(url)
    try:
        parsed = make_url(url)
    except Exception:
        raise ArchiveError("archive URL '%s' is not a database URL (sqlite:///PATH or "
                           "postgresql://USER@HOST/DB)" % display_url(url))
    backend = parsed.get_backend_name()
    if backend == "sqlite":
        path = parsed.database
        if not path or path == ":memory:":
            raise ArchiveError("archive URL '%s' names no file" % display_url(url))
        directory = os.path.dirname(os.path.abspath(path))
        os.makedirs(directory, exist_ok=True)
        engine = sa.create_engine(parsed, connect_args={"timeout": 60},
                                  poolclass=sa.pool.NullPool, future=True)
        _sqlite_transactions(engine)
        return engine
    if backend == "postgresql":
        return sa.create_engine(parsed, poolclass=sa.pool.NullPool, future=True)
    raise ArchiveError("archive URL '%s': unsupported database '%s' (sqlite or postgresql)"
                       % (display_url(url), backend))


def _alembic_config(connection):
    from alembic.config import Config
    config = Config()
    config.set_main_option("script_location", MIGRATIONS_DIR)
    config.attributes["connection"] = connection
    return config


def head_revision():
    from alembic.script import ScriptDirectory
    from alembic.config import Config
    config = Config()
    config.set_main_option("script_location", MIGRATIONS_DIR)
    return ScriptDirectory.from_config(config).get_current_head()


def current_revision(connection):
    from alembic.runtime.migration import MigrationContext
    return MigrationContext.configure(connection).get_current_revision()


def upgrade(engine, revision="head"):
    """Brings the schema to `revision` in one transaction (serialized between processes)."""
    from alembic import command
    with engine.begin() as connection:
        if engine.dialect.name == "postgresql":
            connection.execute(sa.text("SELECT pg_advisory_xact_lock(:key)"),
                               {"key": ADVISORY_LOCK_KEY})
        if revision == "head" and current_revision(connection) == head_revision():
            return
        command.upgrade(_alembic_config(connection), revision)


def open_archive(url):
    """An engine on the archive, its schema at the newest revision. Raises ArchiveError."""
    url = resolve_url(url)
    engine = create_engine(url)
    try:
        upgrade(engine)
    except sa.exc.SQLAlchemyError as error:
        engine.dispose()
        raise ArchiveError("archive %s: %s" % (display_url(url), scrub(first_line(error), url)))
    return engine


def first_line(error):
    text = str(getattr(error, "orig", None) or error)
    return text.strip().splitlines()[0] if text.strip() else type(error).__name__


# --- Results -------------------------------------------------------------------------------------

def load_result(path):
    """A result file: offline_fit's JSON or the calibration node's intrinsics.yaml."""
    try:
        with open(path) as f:
            text = f.read()
    except OSError as error:
        raise ArchiveError("cannot read %s: %s" % (path, error.strerror))
    try:
        result = json.loads(text)
    except ValueError:
        import yaml
        try:
            result = yaml.safe_load(text)
        except yaml.YAMLError as error:
            raise ArchiveError("%s is neither JSON nor YAML: %s" % (path, str(error).splitlines()[0]))
    if not isinstance(result, dict):
        raise ArchiveError("%s is not a result (no key/value document)" % path)
    return result


def _number(result, group, key, where):
    try:
        value = float(result[group][key])
    except (KeyError, TypeError, ValueError):
        raise ArchiveError("%s has no number %s.%s" % (where, group, key))
    if not math.isfinite(value):
        raise ArchiveError("%s: %s.%s is not finite" % (where, group, key))
    return value


def parameter_values(result, where="the result"):
    """{name: (value, expanded, k)} of the nine intrinsic parameters: the expanded uncertainties
    of the uncertainty budget when the result has one, else k = 2 times the standard ones."""
    expanded = (result.get("uncertainty_budget") or {}).get("expanded")
    out = {}
    for name, group, std_group, expanded_group, key in PARAMETERS:
        value = _number(result, group, key, where)
        if expanded:
            k = float(expanded.get("k", DEFAULT_K))
            U = _number(expanded, expanded_group, key, where + " uncertainty_budget.expanded")
        else:
            k = DEFAULT_K
            U = k * _number(result, std_group, key, where)
        out[name] = (value, U, k)
    return out


def has_known_orientation_rows(position_table_text):
    if not position_table_text:
        return False
    header = position_table_text.lstrip("\ufeff").splitlines()[0] if position_table_text else ""
    return "f_x" in [c.strip() for c in header.split(",")]


def result_method(result, position_table_text=None):
    """gimbal, positions or tumble: the result's own `method`, else "positions" for a table of
    known orientations (f_x columns, or a fit with no gimbal phase), else gimbal."""
    method = result.get("method")
    if method:
        if method not in METHODS:
            raise ArchiveError("unknown method '%s' in the result (one of %s)"
                               % (method, ", ".join(METHODS)))
        return method
    if has_known_orientation_rows(position_table_text):
        return "positions"
    phases = result.get("positions")
    if isinstance(phases, dict) and phases and all(int(v or 0) == 0 for v in phases.values()):
        return "positions"
    return "gimbal"


def canonical_json(document):
    return json.dumps(document, sort_keys=True, separators=(",", ":"), allow_nan=True)


def sha256_text(text):
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def sha256_files(paths):
    """One digest over the input files in the order given (a directory: its files, sorted)."""
    digest = hashlib.sha256()
    for path in paths:
        files = ([os.path.join(path, n) for n in sorted(os.listdir(path))
                  if os.path.isfile(os.path.join(path, n))] if os.path.isdir(path) else [path])
        for name in files:
            try:
                with open(name, "rb") as f:
                    for block in iter(lambda: f.read(1 << 20), b""):
                        digest.update(block)
            except OSError as error:
                raise ArchiveError("cannot read input %s: %s" % (name, error.strerror))
    return digest.hexdigest()


def parse_time(text):
    """ISO 8601 (a date, or a date and time; Z or an offset, else UTC) as naive UTC."""
    text = text.strip()
    try:
        when = datetime.datetime.fromisoformat(text[:-1] + "+00:00" if text.endswith("Z") else text)
    except ValueError:
        raise ArchiveError("--time '%s' is not an ISO 8601 date or time (e.g. 2026-03-01 or "
                           "2026-03-01T14:30:00Z)" % text)
    if when.tzinfo is not None:
        when = when.astimezone(datetime.timezone.utc).replace(tzinfo=None)
    return when


def utc_now():
    return datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None, microsecond=0)


def iso(when):
    return when.replace(microsecond=0).isoformat() + "Z"


def result_time(result):
    """The result's own time (its `stamp`, seconds since 1970) when it is a date, else None."""
    stamp = result.get("stamp")
    try:
        stamp = float(stamp)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(stamp) or stamp < EARLIEST_PLAUSIBLE_STAMP:
        return None
    return datetime.datetime.utcfromtimestamp(stamp).replace(microsecond=0)


def make_record(result, device=None, rig=None, when=None, position_table_text=None,
                input_sha256=None, input_paths=None, added_by="archive add"):
    """The row of one result (a dict) and its parameter rows. Raises ArchiveError."""
    quality = result.get("quality")
    if isinstance(quality, dict) and quality.get("pass") is False:
        raise ArchiveError("the result fails the quality gate (%s): it is not a calibration and "
                           "is not archived" % "; ".join(map(str, quality.get("reasons") or [])))
    certificate = result.get("certificate") or {}
    serial = str(certificate.get("serial", "")).strip()
    if device:
        if serial and serial != device:
            raise ArchiveError("--device '%s' differs from the result's certificate serial '%s'"
                               % (device, serial))
        serial = device
    if not serial and str(result.get("device_serial", "")).strip() not in ("", "unnamed"):
        serial = str(result["device_serial"]).strip()  # the calibration node's ~device_serial
    if not serial:
        raise ArchiveError("no device serial: give --device SERIAL (or a budget file whose "
                           "certificate block has `serial`)")
    rig = rig or str(certificate.get("rig", "")).strip()
    certificate_rig = str(certificate.get("rig", "")).strip()
    if rig and certificate_rig and rig != certificate_rig:
        raise ArchiveError("--rig '%s' differs from the result's certificate rig '%s'"
                           % (rig, certificate_rig))
    values = parameter_values(result)
    try:
        g = float(result.get("local_gravity"))
    except (TypeError, ValueError):
        raise ArchiveError("the result has no local_gravity")
    result_text = canonical_json(result)
    if input_sha256:
        if not re.fullmatch(r"[0-9a-fA-F]{64}", input_sha256):
            raise ArchiveError("--input-sha256 '%s' is not 64 hex digits" % input_sha256)
        input_digest = input_sha256.lower()
    elif input_paths:
        input_digest = sha256_files(input_paths)
    elif position_table_text:
        input_digest = sha256_text(position_table_text)
    else:
        input_digest = sha256_text(result_text)
    record = {
        "device_serial": serial,
        "rig": rig or "",
        "time": when or result_time(result) or utc_now(),
        "method": result_method(result, position_table_text),
        "local_gravity": g,
        "model": str(result.get("model_label") or result.get("model") or ""),
        "result_json": result_text,
        "position_table": position_table_text,
        "input_sha256": input_digest,
        "result_sha256": sha256_text(result_text),
        "added_at": utc_now(),
        "added_by": added_by,
    }
    return record, values


def _insert(connection, table, row):
    dialect = connection.dialect.name
    if dialect == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    else:
        from sqlalchemy.dialects.sqlite import insert
    return connection.execute(insert(table).values(**row).on_conflict_do_nothing())


def insert_record(connection, record, values):
    """Inserts inside the caller's transaction; returns (record id, True when new)."""
    inserted = _insert(connection, records, record)
    key = sa.and_(records.c.input_sha256 == record["input_sha256"],
                  records.c.result_sha256 == record["result_sha256"])
    record_id = connection.execute(sa.select(records.c.id).where(key)).scalar_one()
    if inserted.rowcount == 0:
        return record_id, False
    connection.execute(parameters.insert(), [
        {"record_id": record_id, "name": name, "value": v, "expanded": U, "k": k}
        for name, (v, U, k) in values.items()])
    return record_id, True


def add(engine, record, values):
    with engine.begin() as connection:
        return insert_record(connection, record, values)


# --- Reading -------------------------------------------------------------------------------------

def fetch_records(engine, device=None, rig=None):
    """Records (oldest first) with their parameters: dicts with id, device_serial, rig, time,
    method, local_gravity, model, values {name: value}, expanded {name: U}."""
    query = sa.select(records.c.id, records.c.device_serial, records.c.rig, records.c.time,
                      records.c.method, records.c.local_gravity, records.c.model,
                      records.c.input_sha256)
    if device is not None:
        query = query.where(records.c.device_serial == device)
    if rig is not None:
        query = query.where(records.c.rig == rig)
    query = query.order_by(records.c.time, records.c.id)
    with engine.connect() as connection:
        rows = [dict(r._mapping) for r in connection.execute(query)]
        by_id = {r["id"]: r for r in rows}
        for r in rows:
            r["values"], r["expanded"] = {}, {}
        if rows:
            for p in connection.execute(sa.select(parameters).where(
                    parameters.c.record_id.in_(list(by_id)))):
                by_id[p.record_id]["values"][p.name] = p.value
                by_id[p.record_id]["expanded"][p.name] = p.expanded
    return rows


def fetch_result(engine, record_id):
    with engine.connect() as connection:
        row = connection.execute(sa.select(records.c.result_json, records.c.position_table).where(
            records.c.id == record_id)).first()
    if row is None:
        raise ArchiveError("no record %d" % record_id)
    return json.loads(row.result_json), row.position_table


def list_devices(engine):
    with engine.connect() as connection:
        return [tuple(r) for r in connection.execute(
            sa.select(records.c.device_serial, records.c.rig, sa.func.count(records.c.id),
                      sa.func.max(records.c.time))
            .group_by(records.c.device_serial, records.c.rig)
            .order_by(records.c.device_serial, records.c.rig))]
