from tests.registry_fixtures import factory, trained_model_dir, urfd_db, worker_settings  # noqa: F401
