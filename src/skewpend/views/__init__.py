"""Views: figures drawn from result objects (``skewpend.views.figures``; needs matplotlib,
imported on first use) in one style (``skewpend.views.style``)."""
