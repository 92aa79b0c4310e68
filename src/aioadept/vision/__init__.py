"""vision package of aioadept."""
