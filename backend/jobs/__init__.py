"""The job queue of the server domain: the `jobs` table's transitions and claims (`queue`) and
each job kind's parameters (`params`). The web layer queues and cancels jobs through it; the
worker claims and finishes them through it and holds only the handlers."""
