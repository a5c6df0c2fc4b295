# fish completion for zerocal, zerocal-lab, zerocald and zerocal-sim, as the bash one
# (config/bash-completion/zerocal): commands, options and option values asked of the program's
# own --help as one types; session ids asked of the daemon, silently nothing when none answers.
# fish loads a completion by the command's name: zerocal-lab.fish, zerocald.fish and
# zerocal-sim.fish are links to this file.

# One word a line from `$argv --help`, as in the bash completion: "command NAME", "option --NAME",
# "value --NAME" (it takes a value), "choice --NAME VALUE"; nothing of "Moved to zerocal-lab".
function __zerocal_help_words
    $argv --help 2>/dev/null | awk '
    /^[A-Za-z]/ { section = $0; moved = (section ~ /^Moved/) }
    moved { next }
    section ~ /^(SUBCOMMANDS|Subcommands):/ && /^  [a-z]/ { print "command " $1; next }
    section ~ /^Options:/ && /^  -/ {
      n = split($1, names, ",")
      for (i = 1; i <= n; ++i) if (names[i] ~ /^--[a-z]/) {
        print "option " names[i]
        if ($2 ~ /^(TEXT|INT|UINT|FLOAT|BOOLEAN)([:=]|$)/) print "value " names[i]
        if (match($2, /\{[^}]*\}/)) {
          m = split(substr($2, RSTART + 1, RLENGTH - 2), values, ",")
          for (j = 1; j <= m; ++j) print "choice " names[i] " " values[j]
        }
      }
    }' | awk '!seen[$0]++'
end

# The daemon's session ids, through the --host, --port and --token-file on the command line.
function __zerocal_session_ids
    set -l tokens (commandline -opc)
    set -l reach
    for i in (seq 2 (count $tokens))
        if contains -- $tokens[$i] --host --port --token-file; and test $i -lt (count $tokens)
            set -a reach $tokens[$i] $tokens[(math $i + 1)]
        end
    end
    zerocal sessions --all --timeout 2 $reach 2>/dev/null |
        awk '$1 ~ /^[0-9][0-9][0-9][0-9][0-9][0-9][0-9][0-9]T[0-9][0-9][0-9][0-9][0-9][0-9]Z/ { print $1 }'
end

function __zerocal_complete
    set -l tokens (commandline -opc)
    set -l cur (commandline -ct)
    set -l prev $tokens[-1]
    set -l cmd (basename -- $tokens[1])
    for i in (seq 2 (count $tokens))
        if not string match -q -- '-*' $tokens[$i]; and not string match -q -- '-*' $tokens[(math $i - 1)]
            set -a cmd $tokens[$i]
        end
    end
    switch $prev
        case --config --plan-file --joints --plan --out --world --robot --token-file --map --csv --moc --write-truth
            __fish_complete_path $cur
            return
        case --config-dir --data-dir
            __fish_complete_directories $cur
            return
        case --reference
            test $cmd[1] = zerocal; and __zerocal_session_ids
            return
    end
    set -l help (__zerocal_help_words $cmd)
    if string match -q -- '--*' $prev; and contains -- "value $prev" $help
        string replace -rf -- "^choice $prev " '' $help
        return
    end
    if not string match -q -- '-*' $cur
        switch "$cmd[1] $cmd[2]"
            case 'zerocal result' 'zerocal resume' 'zerocal apply' 'zerocal verify' 'zerocal acknowledge'
                test (count $cmd) -eq 2; and __zerocal_session_ids
                return
            case 'zerocal-lab report' 'zerocal-lab apply'
                __fish_complete_directories $cur
                return
        end
        string replace -rf -- '^command ' '' $help
    else
        string replace -rf -- '^option ' '' $help
    end
end

complete -c zerocal -c zerocal-lab -c zerocald -c zerocal-sim -f -a '(__zerocal_complete)'
