"""Job handlers by kind: each takes a JobContext and returns the job's result (a JSON dict)."""

from backend.models.jobs import JobKind
from worker.jobs import evaluate, register, retention, rethreshold, retrain, whatif

HANDLERS = {
    JobKind.RETRAIN: retrain.run,
    JobKind.RETHRESHOLD: rethreshold.run,
    JobKind.EVALUATE: evaluate.run,
    JobKind.REGISTER: register.run,
    JobKind.WHATIF: whatif.run,
    JobKind.RETENTION: retention.run,
}
