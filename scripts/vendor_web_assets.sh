#!/usr/bin/env bash
# Re-vendor the web assets from the npm registry (`npm pack`, no CDN): Swagger UI
# (swagger-ui-dist) and ReDoc's standalone bundle for the API documentation, Leaflet for the
# planner page's map, into api/static/vendor, and rewrite
# api/static/vendor/VENDORED.md with their versions and SHA-256 sums (checked by the tests).
set -euo pipefail
SWAGGER_UI_VERSION="${SWAGGER_UI_VERSION:-5.35.0}"
REDOC_VERSION="${REDOC_VERSION:-2.5.4}"
LEAFLET_VERSION="${LEAFLET_VERSION:-1.9.4}"
cd "$(dirname "$0")/.."
dest=api/static/vendor
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent "swagger-ui-dist@${SWAGGER_UI_VERSION}" "redoc@${REDOC_VERSION}" \
  "leaflet@${LEAFLET_VERSION}" >/dev/null)
mkdir -p "$work/s" "$work/r" "$work/l" "$dest/swagger-ui" "$dest/redoc" "$dest/leaflet/images"
tar xzf "$work/swagger-ui-dist-${SWAGGER_UI_VERSION}.tgz" -C "$work/s"
tar xzf "$work/redoc-${REDOC_VERSION}.tgz" -C "$work/r"
tar xzf "$work/leaflet-${LEAFLET_VERSION}.tgz" -C "$work/l"
cp "$work"/s/package/{swagger-ui-bundle.js,swagger-ui-bundle.js.LICENSE.txt,swagger-ui.css,LICENSE,NOTICE} "$dest/swagger-ui/"
cp "$work"/r/package/bundles/{redoc.standalone.js,redoc.standalone.js.LICENSE.txt} "$dest/redoc/"
cp "$work"/r/package/LICENSE "$dest/redoc/"
# Leaflet: the minified build, its stylesheet and the images the stylesheet names; the source
# map comment is dropped (nothing to fetch)
sed '/^\/\/# sourceMappingURL=/d' "$work/l/package/dist/leaflet.js" > "$dest/leaflet/leaflet.js"
cp "$work"/l/package/dist/leaflet.css "$work"/l/package/LICENSE "$dest/leaflet/"
cp "$work"/l/package/dist/images/*.png "$dest/leaflet/images/"
# ReDoc's sidebar footer loads the Redocly logo from a CDN: point it at an empty inline SVG so
# the page makes no outside request (the only change to the vendored files)
logo='https://cdn.redoc.ly/redoc/logo-mini.svg'
grep -q "$logo" "$dest/redoc/redoc.standalone.js"
sed -i "s#\"$logo\"#\"data:image/svg+xml,%3Csvg xmlns='http://www.w3.org/2000/svg'/%3E\"#" \
    "$dest/redoc/redoc.standalone.js"
if grep -q "cdn.redoc.ly" "$dest/redoc/redoc.standalone.js"; then
  echo "the ReDoc bundle still refers to cdn.redoc.ly" >&2
  exit 1
fi
{
  echo "# Vendored web assets"
  echo
  echo "Fetched with \`scripts/vendor_web_assets.sh\` (\`npm pack\` from the npm registry) and served"
  echo "from /static/vendor by api/routes/web.py, so /docs, /redoc and the planner page's map work"
  echo "offline."
  echo
  echo "* swagger-ui-dist ${SWAGGER_UI_VERSION} (Apache-2.0, see swagger-ui/LICENSE, swagger-ui/NOTICE)"
  echo "* redoc ${REDOC_VERSION} (MIT, see redoc/LICENSE); one change: the sidebar's Redocly logo"
  echo "  URL (cdn.redoc.ly) is replaced by an empty inline SVG, so ReDoc makes no outside request"
  echo "* leaflet ${LEAFLET_VERSION} (BSD-2-Clause, see leaflet/LICENSE): the page's map (zoom, pan,"
  echo "  draggable sites) in local metres (L.CRS.Simple, no tile server); dist/leaflet.js without"
  echo "  its sourceMappingURL line, dist/leaflet.css and dist/images/*.png"
  echo
  echo "SHA-256:"
  echo
  echo '```'
  (cd "$dest" && sha256sum swagger-ui/*.js swagger-ui/*.css redoc/*.js leaflet/*.js leaflet/*.css)
  echo '```'
} > "$dest/VENDORED.md"
echo "vendored swagger-ui-dist ${SWAGGER_UI_VERSION}, redoc ${REDOC_VERSION} and leaflet ${LEAFLET_VERSION} into $dest"
