"""Tracker programs' exports (a CSV table, SpatialAnalyzer, Leica Tracker Pilot) read into SI
samples for ``dhlog import`` (:mod:`dhlog.io.importer`): the table and its units (``table``),
the options (``options``), what each column holds (``layout``), the points in SI units
(``source``), SpatialAnalyzer's point list (``spatialanalyzer``), a joints file (``joints``)."""
