"""Asset ids: the names of output folders and catalog rows (docs/input-format.md, "Asset id").

An item's id is its hints' ``id``, else its photo's name when that is a valid id, else
the name slugified (:func:`asset_id_for`). Ids the output folder uses itself are reserved.
"""

from __future__ import annotations

import hashlib
import re
import unicodedata

#: Asset ids become folder names and catalog keys.
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,127}$")
ID_MAX_LENGTH = 128

#: Names an asset folder must not take because the output folder already uses them:
#: the catalog and SQLite's side files (asset_pipeline.catalog.registry.CATALOG_NAME),
#: the gallery's page, per-asset folder and viewer files (asset_pipeline.gallery.page:
#: ``index.html``, ``gallery/``, ``WEB_DIR_NAME``). Compared case-insensitively (macOS
#: and Windows file systems are). Names starting with "." (``.staging``, ``.previous``,
#: ``.lock`` of asset_pipeline.catalog.batch) are reserved too; :data:`ID_PATTERN`
#: already refuses them.
RESERVED_IDS = frozenset(
    {
        "registry.sqlite",
        "registry.sqlite-wal",
        "registry.sqlite-shm",
        "registry.sqlite-journal",
        "index.html",
        "gallery",
        "gallery_web",
    }
)


def is_reserved_id(asset_id: str) -> bool:
    """True when ``asset_id`` would clash with a file the output folder keeps for itself."""
    return asset_id.startswith(".") or asset_id.casefold() in RESERVED_IDS


def asset_id_for(name: str) -> tuple[str, str | None]:
    """The asset id of a photo named ``name`` (its file name without the suffix).

    Returns ``(name, None)`` when ``name`` already is a valid, unreserved id (see
    :data:`ID_PATTERN`). Otherwise returns a slug and a note saying where it came
    from: accents are dropped (``Küche`` -> ``Kuche``), runs of other characters
    outside ``[A-Za-z0-9_.-]`` become one ``_``, leading characters other than a
    letter or digit and trailing ``_`` / ``.`` are stripped, and the id is cut to 128
    characters; a reserved name gets ``_photo`` appended; a name with nothing usable
    left becomes ``photo_<8 hex digits of its sha1>``.
    """
    if ID_PATTERN.match(name) and not is_reserved_id(name):
        return name, None
    decomposed = unicodedata.normalize("NFKD", name)
    ascii_ish = "".join(c for c in decomposed if not unicodedata.combining(c))
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", ascii_ish)
    slug = re.sub(r"_{2,}", "_", slug)
    slug = re.sub(r"^[^A-Za-z0-9]+", "", slug)
    slug = slug[:ID_MAX_LENGTH].rstrip("_.")
    if not slug:
        slug = "photo_" + hashlib.sha1(name.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    if is_reserved_id(slug):
        slug = slug[: ID_MAX_LENGTH - len("_photo")] + "_photo"
        return slug, f"id {slug!r} made from {name!r} (a name the output folder reserves)"
    return slug, f"id slugified from {name!r}"
