"""Errors the labelling services raise; the routers turn them into HTTP 4xx with the message."""


class LabellingError(ValueError):
    """Bad input: the message names the offending field. Keyword arguments are fields the
    answer carries beside `detail` for a client to act on (e.g. `code`), in `extra`."""

    status_code = 422
    extra: dict[str, object] = {}

    def __init__(self, *args: object, **extra: object) -> None:
        super().__init__(*args)
        if extra:
            self.extra = extra


class NotFound(LabellingError):
    status_code = 404


class Conflict(LabellingError):
    status_code = 409


class Forbidden(LabellingError):
    status_code = 403
