"""Frames at hospital scale: retention policy, PostgreSQL day partitions, SQLite chunked
deletes, Parquet archives and the storage figures the admin sees (issue 20)."""
