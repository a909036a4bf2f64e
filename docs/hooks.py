"""MkDocs hook: fill the configuration reference page from the code.

``docs/reference/config.md`` holds a title and the marker line below; while the site builds, the marker
is replaced by ``pamkin.optimize.config.config_reference_markdown()``, so the page always lists the
optimiser's configuration keys, sections and defaults as the installed code defines them.

Registered in ``mkdocs.yml`` (``hooks: [docs/hooks.py]``). Where pamkin cannot provide the reference
(not installed, or the function missing) the hook logs a warning — which fails ``mkdocs build --strict``
— and the page says so instead of showing stale keys.
"""

from __future__ import annotations

import logging

MARKER = "<!-- config-reference -->"

log = logging.getLogger("mkdocs.hooks.pamkin")


DESIGN_MARKER = "<!-- design-schema -->"


def on_page_markdown(markdown, page, config, files):
    """Replace the config-reference marker by the generated key reference and the design-schema marker by the
    generated design schema (other pages unchanged)."""
    if DESIGN_MARKER in markdown:
        from pamkin.robot.design import design_schema_markdown  # noqa: PLC0415 (at build time only)

        markdown = markdown.replace(DESIGN_MARKER, "\n" + design_schema_markdown() + "\n")
    if MARKER not in markdown:
        return markdown
    try:
        from pamkin.optimize.config import config_reference_markdown  # noqa: PLC0415 (at build time only)
    except ImportError as e:
        log.warning("%s: the configuration reference could not be generated (%s)", page.file.src_path, e)
        return markdown.replace(
            MARKER,
            "\nThe reference could not be generated when this site was built: "
            "`pamkin.optimize.config.config_reference_markdown()` was not available "
            f"(`{e}`). Every key and its default are documented in `optimize/config.py`.\n")
    return markdown.replace(MARKER, "\n" + config_reference_markdown().strip() + "\n")
