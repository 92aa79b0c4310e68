"""sim package of aioadept."""
