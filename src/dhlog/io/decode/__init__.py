"""A log's streams decoded, for :func:`dhlog.io.reader.read_log`: one message's fields by its
schema (``messages``), a stream's channels into blocks of (times, values) — bulk CDR where the
layout allows, message by message otherwise, damaged messages skipped and counted
(``blocks``) —, the bulk decode run chunk by chunk while the log is walked (``columns``), and
the blocks into polars tables (``frames``)."""
