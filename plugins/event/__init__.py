"""Event kinds (an event's ``kind``), one registered module each."""
