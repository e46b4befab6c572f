"""Backend settings: one pydantic-settings class, read from VIGIL_* environment variables."""

import secrets
from pathlib import Path

from pydantic import Field, model_validator
from pydantic_settings import SettingsConfigDict

from backend.storage.settings import StorageSettings

REPO_ROOT = Path(__file__).resolve().parent.parent


class Settings(StorageSettings):
    model_config = SettingsConfigDict(env_prefix="VIGIL_", env_file=".env", extra="ignore")

    database_url: str = Field(
        default=f"sqlite:///{REPO_ROOT / 'var' / 'vigil.db'}",
        description="SQLAlchemy URL; postgresql+psycopg://... selects PostgreSQL",
    )
    # The request threads (40), the frame writer and the duties use connections at once; a
    # connection opened beyond the kept ones is closed when returned, and a thousand robots
    # reconnecting then cost PostgreSQL a new server process per checkout.
    database_pool_size: int = Field(
        default=30,
        ge=1,
        le=200,
        description="PostgreSQL: connections each backend process keeps open",
    )
    database_max_overflow: int = Field(
        default=10,
        ge=0,
        le=200,
        description="PostgreSQL: connections opened beyond database_pool_size for a peak "
        "(closed again when returned)",
    )
    secret_key: str = Field(
        default="",
        description="HMAC key signing browser sessions; empty: a random key kept in "
        "VIGIL_SECRET_KEY_FILE (every replica must share one key)",
    )
    secret_key_file: Path = Field(
        default=REPO_ROOT / "var" / "secret_key",
        description="where the generated session key is kept (mode 600) when none is set",
    )
    access_token_minutes: int = Field(default=12 * 60, description="browser session lifetime")
    cookie_secure: bool = Field(default=False, description="mark the session cookie Secure")
    login_user_free_failures: int = Field(
        default=5, ge=1, description="wrong passwords for one user name before its lockout starts"
    )
    login_client_free_failures: int = Field(
        default=20,
        ge=1,
        description="wrong passwords from one client address (any user) before its lockout starts",
    )
    login_lockout_base_s: float = Field(
        default=2.0,
        gt=0,
        description="first lockout after the free failures; it doubles with each further failure",
    )
    login_lockout_max_s: float = Field(default=900.0, gt=0, description="longest login lockout")
    login_failure_memory_s: float = Field(
        default=3600.0,
        gt=0,
        description="failures are forgotten after this long without a new one",
    )
    login_hash_concurrency: int = Field(
        default=1,
        ge=1,
        description="password verifications run at once (argon2 in a worker thread), so a login "
        "flood cannot starve robot ingest of CPU",
    )
    login_hash_nice: int = Field(
        default=19,
        ge=0,
        le=19,
        description="how much lower the scheduling priority of password hashing threads is "
        "(ingest first); 0: same as the rest",
    )
    login_queue_wait_s: float = Field(
        default=2.0,
        ge=0,
        description="longest a login waits for a verification slot before a 503 with Retry-After",
    )
    login_queue_max: int = Field(
        default=32, ge=0, description="logins waiting for a slot; more get a 503 at once"
    )
    trusted_origins: list[str] = Field(
        default_factory=list,
        description="origins besides the backend's own allowed to send cookie-authenticated "
        'writes and open the browser socket, JSON: ["https://vigil.example"]',
    )
    browser_auth_timeout_s: float = Field(
        default=5.0, gt=0, description="time a browser socket has to send its auth message"
    )
    frontend_dir: Path = Field(
        default=REPO_ROOT / "frontend" / "dist", description="built frontend served at /"
    )
    model_store_dir: Path = Field(
        default=REPO_ROOT / "var" / "models", description="registered model files"
    )
    redis_url: str | None = Field(
        default=None, description="redis://... enables alarm fan-out across backend replicas"
    )
    redis_channel: str = Field(default="vigil:alarms", description="Redis pub/sub channel")
    ingest_flush_ms: float = Field(
        default=20, description="longest a received frame waits before its batch is committed"
    )
    ingest_flush_frames: int = Field(default=500, description="frames that force an early commit")
    ingest_max_flush_frames: int = Field(
        default=2000,
        ge=1,
        description="most frames (or frameless messages) one commit takes; the rest go in the "
        "next, so a commit stays short however far behind the writer is",
    )
    escalation_seconds: float = Field(
        default=60, description="an open Emergency not acknowledged in this time escalates"
    )
    escalation_seconds_by_ward: dict[str, float] = Field(
        default_factory=dict,
        description='per-ward escalation time, JSON: {"ward-3a": 30}; others use the default',
    )
    escalation_max_level: int = Field(
        default=3, description="escalation stops after this many levels"
    )
    missed_escalation_chain: list[str] = Field(
        default_factory=lambda: ["charge nurse", "rapid-response team"],
        description="who a missed Emergency escalates to next, in order, JSON list",
    )
    missed_escalation_chain_by_ward: dict[str, list[str]] = Field(
        default_factory=dict,
        description='per-ward chain, JSON: {"ward-3a": ["charge nurse 3a", "rapid-response team"]}',
    )
    missed_escalation_seconds: float = Field(
        default=120, description="a missed Emergency still unanswered this long goes to the next"
    )
    realarm_minutes: float = Field(
        default=15, description="an acknowledged alarm not resolved in this time re-alarms"
    )
    stream_stall_seconds: float = Field(
        default=5.0,
        description="no frame for this long during a transport raises a technical alarm",
    )
    patient_unseen_seconds: float = Field(
        default=5.0,
        description="frames flow but none shows the patient for this long during a transport: "
        "technical alarm patient_not_seen (cleared when the patient is seen again)",
    )
    robot_offline_seconds: float = Field(
        default=10.0,
        description="no message from a robot for this long during a transport: robot offline",
    )
    storage_stall_seconds: float = Field(
        default=2.0,
        description="a frame write blocked this long raises the storage-stalled technical alarm "
        "on the nurse board (cleared when the write goes through)",
    )
    unstored_alarm_ms: float = Field(
        default=300,
        description="an Emergency not stored within this time is pushed to the nurse board "
        "marked not yet stored, then replaced by the stored alarm (fail open)",
    )
    ready_storage_stall_s: float = Field(
        default=2.0,
        gt=0,
        description="readiness (/api/health/ready) answers 503 with the reason while the frame "
        "writer's current write has been blocked longer than this",
    )
    alarm_list_timeout_ms: float = Field(
        default=500,
        gt=0,
        description="GET /api/alarms gives storage this long (PostgreSQL statement and lock "
        "timeout, SQLite busy timeout), then answers from the live board state, marked stale",
    )
    alert_manager: str | None = Field(
        default=None,
        description="IHE PCD ACM Alert Manager (phones, pagers) as host:port: every alarm change "
        "is sent to it as HL7 ORU^R40 over MLLP; empty: alarms stay on the board",
    )
    alert_manager_by_ward: dict[str, str] = Field(
        default_factory=dict,
        description='per-ward Alert Manager, JSON: {"ward-3a": "10.1.3.7:2575"}; others use '
        "alert_manager",
    )
    alert_facility: str = Field(
        default="HOSPITAL", max_length=60, description="MSH-4 sending facility of ORU^R40"
    )
    alert_status_listen: str | None = Field(
        default=None,
        description="host:port where the Alert Manager sends its ORA^R41 dispositions "
        "(delivered, read, accepted, rejected); empty: none are received",
    )
    alert_status_allowed_peers: list[str] = Field(
        default_factory=list,
        description="hosts allowed to send ORA^R41 besides the Alert Managers' own, JSON list",
    )
    alert_ack_timeout_s: float = Field(
        default=5.0, gt=0, description="wait this long for the Alert Manager's ACK, then resend"
    )
    alert_retry_s: float = Field(
        default=2.0, gt=0, description="an unacknowledged alarm message is sent again after this"
    )
    alert_poll_s: float = Field(
        default=0.5,
        gt=0,
        le=60,
        description="the alarm distribution's sender looks for queued messages at least this "
        "often (it is woken at once by changes of its own replica and, through Redis, of the "
        "others)",
    )
    alarm_distribution_down_s: float = Field(
        default=10.0,
        gt=0,
        description="an Alert Manager unreachable this long raises the technical alarm "
        '"alarm distribution down" on the boards of its wards',
    )
    stall_actions_path: Path | None = Field(
        default=None,
        description="journal of acknowledgements and resolutions of alarms not yet stored "
        "(applied once stored); default: beside the SQLite file, or var/ for PostgreSQL",
    )
    health_timeout_s: float = Field(
        default=2.0,
        description="readiness (/api/health/ready): longest wait for the database "
        "and Redis to answer",
    )
    gil_switch_interval_s: float = Field(
        default=0.0005, description="sys.setswitchinterval of the backend process (ingest latency)"
    )
    monitor_interval_s: float = Field(default=1.0, description="alarm monitor period")
    duties_retry_s: float = Field(
        default=1.0,
        gt=0,
        le=60,
        description="how often a replica without the duties (alarm monitor, alarm distribution) "
        "tries to take them, and the holder checks it still holds them",
    )
    replica_name: str = Field(
        default="",
        max_length=64,
        description="this replica's name in logs and /api/health (empty: its process id)",
    )
    urfd_dir: Path | None = Field(
        default=None,
        description="URFD dataset directory; None = ../shared/datasets/urfd next to the repo",
    )
    labelling_model_dir: Path | None = Field(
        default=REPO_ROOT / "var" / "models" / "default-walking",
        description="model that fills the labelling timeline's probability lane when a video "
        "has no stored scores; None disables it",
    )
    rgb_cache_frames: int = Field(default=600, description="decoded RGB frames kept in memory")
    viser_host: str = Field(default="127.0.0.1", description="3D view (viser) listens here")
    viser_port: int = Field(default=8090, description="3D view (viser) port, started on first use")
    max_upload_bytes: int = Field(
        default=64 * 2**20,
        gt=0,
        description="largest HTTP request body (a labelling import file) in bytes; a larger one "
        "is answered 413 as it streams in, before it is read",
    )
    robot_hello_timeout_s: float = Field(default=5.0, description="time a robot has to say hello")
    gate_false_alarm_budget: float = Field(
        default=0.15,
        description="promotion gate: largest share of gold-set daily-activity recordings with a "
        "false alarm",
    )
    gate_latency_ms: float = Field(
        default=33.0, description="promotion gate: per-frame p95 latency bound (30 frames/s)"
    )
    require_second_approver: bool = Field(
        default=False, description="a promotion waits for a second engineer's approval"
    )
    assignment_resend_s: float = Field(
        default=30.0, description="resend a model assignment a robot has not switched to"
    )

    def escalation_seconds_for(self, ward: str) -> float:
        return self.escalation_seconds_by_ward.get(ward, self.escalation_seconds)

    def missed_escalation_chain_for(self, ward: str) -> list[str]:
        return self.missed_escalation_chain_by_ward.get(ward, self.missed_escalation_chain)

    @model_validator(mode="after")
    def _session_key(self) -> "Settings":
        if not self.secret_key:
            self.secret_key = load_or_create_secret(self.secret_key_file)
        return self


def load_or_create_secret(path: Path) -> str:
    """A random key generated once per installation, readable only by its owner."""
    if path.exists():
        return path.read_text().strip()
    path.parent.mkdir(parents=True, exist_ok=True)
    key = secrets.token_urlsafe(48)
    path.touch(mode=0o600)
    path.write_text(key)
    return key


def get_settings() -> Settings:
    return Settings()
