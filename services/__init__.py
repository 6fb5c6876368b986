"""The processes the supervisor starts: robot driver, tracker_ingest, scaler, planner, safety monitor
and router, each a thin shell around its core in `shared`."""
