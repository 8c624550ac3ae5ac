#!/usr/bin/env bash
# Checks of the source tree that no compiler makes (docs/reliability.md, "Source checks"):
#   a. a comment that names a file names one that exists. Checked: the comments of the
#      *.h *.hpp *.cpp *.glsl *.vert *.frag *.sh *.cmake and CMakeLists.txt files under
#      common/ precompute/ relight/ tools/ tests/ (and the top-level CMakeLists.txt).
#      - A path whose first folder is a top-level folder of the repository (common/,
#        docs/, tests/, ...) exists relative to the root; without an extension it may
#        also be a module (common/mesh: common/mesh.h and .cpp).
#      - Any other path ending in a source extension or .md exists relative to the root
#        or to the commenting file's folder (a viewer source may name its shaders folder).
#      - A bare name with a source extension (view.cpp) is the name of a file somewhere
#        in the tree.
#      <placeholder> and * in a name match any text (test_<module>.cpp), so the pattern
#      must match some file; a bare extension pattern (*.sh) names no file. The
#      allow-lists below name what a comment may mention but the tree never holds.
#   b. no "issue N" / "issue #N" (any case) in the code of common/ precompute/ relight/
#      tools/ (comments, help text and strings alike: history belongs in docs/).
#   c. every header of a module folder has its module name (the file stem) as a word of
#      docs/building.md's "Layout" section (from "## Layout" to the next "## " heading).
#   d. a room's code includes only its own room and the rooms below it (allowedIncludes).
# Usage: source_check.sh SOURCE_ROOT. Prints one line "file:line: reason" per finding and
# exits 1 when there is any, 0 when there is none (2 for a bad root). Needs only bash,
# grep, sed, find and sort (no python: it runs on a fresh CI machine).
set -u
export LC_ALL=C

root=${1:?usage: source_check.sh SOURCE_ROOT}
cd "$root" 2> /dev/null || { echo "source_check.sh: cannot enter $root" >&2; exit 2; }

sourceDirs=(common precompute relight tools tests)
codeDirs=(common precompute relight tools)
moduleDirs=(common precompute/passes precompute/job relight/render relight/prt relight/pointlight
            relight/combined relight/viewer tools/reference)
sourceExt='h|hpp|cpp|cc|c|glsl|vert|frag|sh|cmake|py'  # what a bare name is checked for
pathExt="$sourceExt|md"                                 # what a path outside the top folders is

# --- allow-lists (rule a) ----------------------------------------------------------------
# Files that only a build creates (the shaders embedded by relight/viewer/shaders/embed.cmake).
generatedFiles=(relight/viewer/shaders/shaders.h shaders/shaders.h shaders.h)
# Folders whose contents are downloaded or written by the tools (git-ignored).
untrackedPrefixes=(data/envmaps data/meshes data/.cache out build)
# Headers of the dependencies (docs/building.md, "Dependencies") and of the system.
externalPrefixes=(embree3/ glm/ tbb/ oneapi/ CLI/ OpenImageIO/ OpenEXR/ Imath/ OpenMesh/ Eigen/
                  GLFW/ GL/ gtest/ gmock/ benchmark/ sys/ linux/ imgui/ backends/)
externalFiles=(imgui.h imgui_impl_glfw.h imgui_impl_opengl3.h zlib.h mpi.h unistd.h omp.h
               immintrin.h xmmintrin.h emmintrin.h cpuid.h)

failures=0
report() {  # file line reason
    echo "$1:$2: $3"
    failures=$((failures + 1))
}

# Every file of the tree (not .git, build directories or outputs): names and top folders.
declare -A haveName=()
while IFS= read -r f; do haveName[${f##*/}]=1; done < <(
    find . \( -name .git -o -name 'build*' -o -name out \) -prune -o -type f -print)
mapfile -t topDirs < <(find . -mindepth 1 -maxdepth 1 -type d ! -name '.*' ! -name 'build*' ! -name out |
                       sed 's#^\./##')

inList() {  # needle items...
    local needle=$1 item
    shift
    for item in "$@"; do [[ $needle == "$item" ]] && return 0; done
    return 1
}
hasPrefix() {  # text prefixes...
    local text=$1 prefix
    shift
    for prefix in "$@"; do [[ $text == "$prefix"* ]] && return 0; done
    return 1
}
underAny() {  # path folders...: the path is one of the folders or lies under one
    local path=$1 folder
    shift
    for folder in "$@"; do [[ $path == "$folder" || $path == "$folder"/* ]] && return 0; done
    return 1
}
# glob=$1 with every <placeholder> turned into *.
globOf() {
    glob=$1
    while [[ $glob =~ ^(.*)\<[^\<\>]*\>(.*)$ ]]; do glob="${BASH_REMATCH[1]}*${BASH_REMATCH[2]}"; done
}
# The path (a glob allowed) matches an existing file or folder; a path without an
# extension also matches a module's files.
pathExists() {
    globOf "$1"
    compgen -G "$glob" > /dev/null && return 0
    [[ ${glob##*/} != *.* ]] && compgen -G "$glob.*" > /dev/null
}
# The bare name (a glob allowed) is the name of a file of the tree.
nameExists() {
    local name
    globOf "$1"
    if [[ $glob == *[*?]* ]]; then
        for name in "${!haveName[@]}"; do
            # shellcheck disable=SC2053
            [[ $name == $glob ]] && return 0
        done
        return 1
    fi
    [[ -n ${haveName[$glob]+x} ]]
}

# The comments of files, as lines "file:line:comment text" (lines without a comment are
# left out). Input: the files' lines as grep -H -n prints them, "file:line:text".
hashComments() {
    # From a '#' at the start of a line or after a blank, outside "..." (not a #! line).
    sed -E -e '/^[^:]*:1:#!/d' \
           -e 's/^([^:]*:[0-9]+:)(([^"#]|"([^"\\]|\\.)*")*[[:space:]]|[[:space:]]*)#(.*)$/\1\5/;t' -e d
}
slashComments() {
    # '//' outside "..."; a '/*' ... '*/' on one line; every line of a block from the line
    # that opens it (a '/*' after a blank or punctuation, not a path's) to its '*/'.
    sed -E -e '\#^[^:]*:[0-9]+:(|.*[[:space:];(){},=])/\*([^*]|\*+[^*/])*\**$#,\#\*/#{p;d}' \
           -e 's#^([^:]*:[0-9]+:)(([^"/]|/[^/*"]|"([^"\\]|\\.)*")*)//(.*)$#\1\5#;t' \
           -e 's#^([^:]*:[0-9]+:)(([^"/]|/[^/*"]|"([^"\\]|\\.)*")*)/\*(.*)\*/.*$#\1\5#;t' -e d
}

# One name a comment mentions: report it when it names nothing.
checkName() {  # file dir line token
    local file=$1 dir=$2 line=$3 path=$4
    if [[ $path == */* ]]; then
        path=${path%/}
        if inList "${path%%/*}" "${topDirs[@]}" out build; then
            underAny "$path" "${untrackedPrefixes[@]}" && return
            inList "$path" "${generatedFiles[@]}" && return
            pathExists "$path" || report "$file" "$line" "comment names $4, which does not exist"
        elif [[ $path =~ \.($pathExt)$ ]]; then
            hasPrefix "$path" "${externalPrefixes[@]}" && return
            inList "$path" "${generatedFiles[@]}" && return
            pathExists "$path" || pathExists "$dir/$path" ||
                report "$file" "$line" "comment names $4, which does not exist"
        fi
    elif [[ $path =~ \.($sourceExt)$ && $path != .* && $path != \*.* ]]; then
        inList "$path" "${generatedFiles[@]}" "${externalFiles[@]}" && return
        nameExists "$path" || report "$file" "$line" "comment names $4, which is not in the tree"
    fi
}

# --- a. comments naming files ---------------------------------------------------------------
commentLines=0
checkComments() {  # reads "file:line:comment text"
    local file line text token dir
    set -f  # the words below are names and patterns, never globs to expand here
    while IFS=: read -r file line text; do
        commentLines=$((commentLines + 1))
        dir=${file%/*}
        [[ $dir == "$file" ]] && dir=.
        # Names are runs of these characters (what grep -o would cut out).
        for token in ${text//[^A-Za-z0-9_.*<>\/+-]/ }; do
            # Trailing punctuation is not part of a name; URLs and absolute paths are not
            # the repository's.
            while [[ $token == *[.,:\;-] ]]; do token=${token%?}; done
            [[ -z $token || $token == /* || $token == *//* ]] && continue
            [[ $token == */* || $token =~ \.($pathExt)$ ]] || continue
            # "visibility.vert/.frag": two names.
            if [[ $token =~ ^(.*)\.([A-Za-z0-9]+)/\.([A-Za-z0-9]+)$ ]]; then
                local stem=${BASH_REMATCH[1]} ext1=${BASH_REMATCH[2]} ext2=${BASH_REMATCH[3]}
                checkName "$file" "$dir" "$line" "$stem.$ext1"
                checkName "$file" "$dir" "$line" "$stem.$ext2"
            else
                checkName "$file" "$dir" "$line" "$token"
            fi
        done
    done
    set +f
}

mapfile -t hashFiles < <(find "${sourceDirs[@]}" -type f \( -name '*.sh' -o -name '*.cmake' -o -name CMakeLists.txt \) |
                         sort)
hashFiles+=(CMakeLists.txt)
mapfile -t slashFiles < <(find "${sourceDirs[@]}" -type f \( -name '*.h' -o -name '*.hpp' -o -name '*.cpp' \
                              -o -name '*.glsl' -o -name '*.vert' -o -name '*.frag' \) | sort)
checkComments < <(
    { grep -H -n '' "${hashFiles[@]}" | hashComments
      grep -H -n '' "${slashFiles[@]}" | slashComments; } |
    grep -E "^[^:]*:[0-9]+:.*(/|\.($pathExt)([^A-Za-z0-9_]|$))")
# The tree's comments name hundreds of files: none found means the extraction broke.
((commentLines > 0)) || report tests/source_check.sh 1 "found no comment naming a file: the check itself is broken"

# --- b. issue numbers in code -----------------------------------------------------------------
mapfile -t codeFiles < <(find "${codeDirs[@]}" -type f \( -name '*.h' -o -name '*.hpp' -o -name '*.cpp' \
                             -o -name '*.glsl' -o -name '*.vert' -o -name '*.frag' -o -name '*.sh' -o -name '*.py' \
                             -o -name '*.cmake' -o -name CMakeLists.txt \) | sort)
while IFS=: read -r file line _; do
    report "$file" "$line" "issue number in code (history and issue references belong in docs/)"
done < <(grep -H -n -i -E '(^|[^A-Za-z0-9_])issues?[[:space:]]*#?[0-9]+' "${codeFiles[@]}")

# --- c. modules in docs/building.md's map ------------------------------------------------------
declare -A layoutWord=()
while IFS= read -r word; do layoutWord[$word]=1; done < <(
    sed -n '/^## Layout/,/^## /p' docs/building.md 2> /dev/null | grep -o -E '[A-Za-z0-9_]+')
if ((${#layoutWord[@]} == 0)); then
    report docs/building.md 1 'no "## Layout" section'
else
    while IFS= read -r header; do
        stem=${header##*/}
        stem=${stem%.h}
        [[ -n ${layoutWord[$stem]+x} ]] ||
            report "$header" 1 "module $stem is missing from docs/building.md's Layout section"
    done < <(find "${moduleDirs[@]}" -maxdepth 1 -type f -name '*.h' | sort)
fi

# --- d. includes run down the floors -----------------------------------------------------------
# A room's code includes only its own room and the rooms below it, the order its libraries
# link in (docs/building.md, "Layout"); the executables at a folder's top (*_main.cpp) may
# include any room of their folder. tools/reference's library stands on relight/render, and
# on relight/pointlight for the light description alone (point_lights.h: Light, its parser,
# the inside test), so that it takes lights as prt-pointlight does; its irradiance code is
# its own (docs/reference.md, "Point and directional lights").
allowedIncludes() {  # room -> the folders it may include
    case "$1" in
        common) echo "common" ;;
        precompute/passes) echo "common precompute/passes" ;;
        precompute/job) echo "common precompute/passes precompute/job" ;;
        relight/render) echo "common relight/render" ;;
        relight/prt) echo "common relight/render relight/prt" ;;
        relight/pointlight) echo "common relight/render relight/pointlight" ;;
        relight/combined) echo "common relight/render relight/prt relight/pointlight relight/combined" ;;
        relight/viewer) echo "common relight/render relight/prt relight/pointlight relight/combined relight/viewer" ;;
        tools/reference) echo "common relight/render relight/pointlight tools/reference" ;;
    esac
}
for room in "${moduleDirs[@]}"; do
    read -r -a allowed <<< "$(allowedIncludes "$room")"
    while IFS=: read -r file line text; do
        included=$(sed -E 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"([^"]+)".*/\1/' <<< "$text")
        [[ $included == */* ]] || continue
        ok=0
        for folder in "${allowed[@]}"; do
            if [[ ${included%/*} == "$folder" ]]; then ok=1; break; fi
        done
        # relight/viewer/shaders/shaders.h is generated into the viewer's own room.
        [[ $room == relight/viewer && $included == relight/viewer/shaders/* ]] && ok=1
        ((ok)) || report "$file" "$line" "$room includes $included, above its floor (allowed: ${allowed[*]})"
    done < <(find "$room" -maxdepth 1 -type f \( -name '*.h' -o -name '*.cpp' \) ! -name '*_main.cpp' -print0 |
             xargs -0 grep -H -n -E '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' 2> /dev/null)
done

if ((failures > 0)); then
    echo "source_check.sh: $failures finding(s)" >&2
    exit 1
fi
exit 0
