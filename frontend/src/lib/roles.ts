import type { Role } from "../api/types";

/** The page each role lands on after signing in. */
export function homeFor(role: Role): string {
  switch (role) {
    case "annotator":
      return "/annotate";
    case "nurse":
      return "/nurse";
    case "engineer":
    case "admin":
      return "/engineer";
  }
}

/** Which roles may open a section; admins may open every section. */
export const SECTION_ROLES: Record<"annotate" | "nurse" | "engineer" | "admin", Role[]> = {
  annotate: ["annotator", "engineer", "admin"],
  nurse: ["nurse", "admin"],
  engineer: ["engineer", "admin"],
  admin: ["admin"],
};

export function mayOpen(role: Role, section: keyof typeof SECTION_ROLES): boolean {
  return SECTION_ROLES[section].includes(role);
}

/** Where to go after signing in: the page asked for (deep link) if the role may open it. */
export function landingPage(role: Role, requested?: string | null): string {
  const section = requested?.match(/^\/(annotate|nurse|engineer|admin)(\/|$)/)?.[1] as
    | keyof typeof SECTION_ROLES
    | undefined;
  return section && mayOpen(role, section) ? requested! : homeFor(role);
}
