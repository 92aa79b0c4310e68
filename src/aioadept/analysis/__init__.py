"""analysis package of aioadept."""
