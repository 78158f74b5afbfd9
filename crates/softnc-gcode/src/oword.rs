//! What an O-line does ([`OKind`]): the O-word keywords of LinuxCNC's control flow
//! (`sub`, `call`, `while`, `if`, …) and Fanuc's M98/M99 subprograms, read by
//! [`crate::interp`]'s O-line reader and compiled into a kept line's plan
//! ([`crate::compiled::OPlan`]).

/// What an O-line does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OKind {
    /// `sub`
    Sub,
    /// `endsub`
    EndSub,
    /// `call`
    Call,
    /// `do`
    Do,
    /// `while`
    While,
    /// `repeat`
    Repeat,
    /// `if`
    If,
    /// `elseif`
    ElseIf,
    /// `else`
    Else,
    /// `endif`
    EndIf,
    /// `break`
    Break,
    /// `continue`
    Continue,
    /// `endwhile`
    EndWhile,
    /// `endrepeat`
    EndRepeat,
    /// `return`
    Return,
    /// A bare `O1234` (Fanuc-style subprogram start, called with M98).
    Bare,
    /// `M98 P… [L…]`: call a Fanuc-style subprogram (L times).
    M98,
    /// `M99` in a subprogram: return.
    M99,
}

impl OKind {
    pub(crate) fn name(self) -> &'static str {
        use OKind::*;
        match self {
            Sub => "sub",
            EndSub => "endsub",
            Call => "call",
            Do => "do",
            While => "while",
            Repeat => "repeat",
            If => "if",
            ElseIf => "elseif",
            Else => "else",
            EndIf => "endif",
            Break => "break",
            Continue => "continue",
            EndWhile => "endwhile",
            EndRepeat => "endrepeat",
            Return => "return",
            Bare => "",
            M98 => "M98",
            M99 => "M99",
        }
    }
    /// sub, endsub, call and return name subroutines (global); the others are
    /// labels local to the subroutine they are in.
    pub(crate) fn global(self) -> bool {
        matches!(
            self,
            OKind::Sub
                | OKind::EndSub
                | OKind::Call
                | OKind::Return
                | OKind::Bare
                | OKind::M98
                | OKind::M99
        )
    }
}
