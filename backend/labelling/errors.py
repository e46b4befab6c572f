"""Errors the labelling services raise; the routers turn them into HTTP 4xx with the message."""


class LabellingError(ValueError):
    """Bad input: the message names the offending field."""

    status_code = 422


class NotFound(LabellingError):
    status_code = 404


class Conflict(LabellingError):
    status_code = 409


class Forbidden(LabellingError):
    status_code = 403
