"""Event-driven simulation: contacts, joint stops and stick-slip friction, impacts."""
