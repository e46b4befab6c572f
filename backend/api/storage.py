"""Storage (admin): frames and bytes per day and per robot, the next retention run, runs,
archives (Parquet) and importing an archive again; queuing a retention run (dry or real)."""

from fastapi import APIRouter, HTTPException, status

from backend.deps import CurrentUser, DbId, SessionDep, SettingsDep
from backend.jobs.schemas import JobOut
from backend.services import ServicesDep
from backend.storage import archive, queries, service
from backend.storage.schemas import ArchiveIn, ArchiveOut, RetentionIn, StorageSummary

router = APIRouter(prefix="/api/storage", tags=["storage"])


@router.get("/summary")
def storage_summary(
    services: ServicesDep, user: CurrentUser, fresh: bool = False
) -> StorageSummary:
    """Cached for a minute (the figures scan every frame); ?fresh=true recomputes."""
    return services.storage_summary.get(services.session_factory, services.settings, fresh)


@router.post("/retention", status_code=status.HTTP_201_CREATED)
def queue_retention(body: RetentionIn, session: SessionDep, user: CurrentUser) -> JobOut:
    """Queue a retention run for the worker (a dry run records what would go)."""
    return JobOut.model_validate(service.queue_retention(session, body.dry_run, user.id))


@router.get("/archives")
def list_archives(session: SessionDep, user: CurrentUser) -> list[ArchiveOut]:
    return [service.archive_out(session, a) for a in queries.archives(session)]


@router.post("/archives", status_code=status.HTTP_201_CREATED)
def create_archives(
    body: ArchiveIn, session: SessionDep, user: CurrentUser, settings: SettingsDep
) -> list[ArchiveOut]:
    """Export a video, or every video of a transport, to Parquet (one file per video)."""
    try:
        made = service.make_archives(session, settings, body.video_id, body.transport_id, user.id)
    except archive.ArchiveError as error:
        raise HTTPException(status.HTTP_404_NOT_FOUND, str(error)) from None
    return [service.archive_out(session, a) for a in made]


@router.post("/archives/{archive_id}/import")
def import_archive(archive_id: DbId, session: SessionDep, user: CurrentUser) -> ArchiveOut:
    """Bring the archived frames (and labels) back for labelling or training; idempotent."""
    found = queries.archive_by_id(session, archive_id)
    if found is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"archive {archive_id} not found")
    try:
        archive.import_archive(session, found)
    except (archive.ArchiveError, OSError) as error:
        raise HTTPException(status.HTTP_409_CONFLICT, str(error)) from None
    return service.archive_out(session, found)
