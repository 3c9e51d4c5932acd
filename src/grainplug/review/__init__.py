"""Review an analysis in the browser: the diagram, any frame with its edges, corrections.

See :class:`~grainplug.review.server.ReviewServer` and ``grainplug review``.
"""

from .server import ReviewServer, ReviewSession, review_targets

__all__ = ["ReviewServer", "ReviewSession", "review_targets"]
