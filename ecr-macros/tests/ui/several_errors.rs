use ecr_macros::ecr_method;

ecr_method!(r = 0, colour = red, s = 1, s = 2);

fn main() {}
